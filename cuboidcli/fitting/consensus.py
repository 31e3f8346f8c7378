"""Object boxes that several fits of one room agree on.

A room's fit is random: each seed draws other minimal sets, so the cuboids that seed the object boxes
differ, and so do the boxes. A piece of furniture comes out in most fits, in nearly the same box; a
fragment (a scrap of a table's top, half a sofa, two chairs in one box) comes out in one fit and not in the
next. The room is therefore fitted :attr:`~cuboidcli.fitting.config.FitConfig.object_fits` times (the
first fit is the one whose cuboids are returned), each fit's points grouped into objects, and an object
box is kept when at least a majority of the fits hold a box of it: boxes of different fits at 3D IoU
:data:`AGREE_IOU` or more are the same object. Of the boxes that agree, the one that agrees best with the
others (the largest sum of IoU) stands for the object, its score scaled by the share of fits that found it.

On the 10 real ScanNet scans and the sequences rendered from them, five fits raised recall at IoU 0.25 and
precision together and made them far less dependent on the seed (docs/scenes.md). Numpy, float64.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.objects import SceneObject

#: Boxes of two fits at this 3D IoU or more are boxes of one object.
AGREE_IOU = 0.25


def _footprint(box: Cuboid, R: np.ndarray) -> tuple[np.ndarray, float, float]:
    """An upright box's footprint (4, 2) in cyclic order and its bottom and top, in the level frame of ``R``
    (its z the room's up)."""
    axes = R.T @ box.rotation
    k = int(np.argmax(np.abs(axes[2])))
    a, b = (j for j in range(3) if j != k)
    centre = R.T @ box.center
    u, v = axes[:2, a] * box.half_size[a], axes[:2, b] * box.half_size[b]
    c = centre[:2]
    corners = np.array([c + u + v, c - u + v, c - u - v, c + u - v])
    reach = float(np.abs(axes[2]) @ box.half_size)
    return corners, centre[2] - reach, centre[2] + reach


def _area(poly: np.ndarray) -> float:
    if len(poly) < 3:
        return 0.0
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(x @ np.roll(y, -1) - y @ np.roll(x, -1)))


def _clip(poly: np.ndarray, clipper: np.ndarray) -> np.ndarray:
    """The part of convex polygon ``poly`` (K, 2) inside convex polygon ``clipper`` (4, 2), either turn."""
    sign = 1.0 if _signed(clipper) > 0 else -1.0
    out = poly
    for i in range(len(clipper)):
        if not len(out):
            break
        p, q = clipper[i], clipper[(i + 1) % len(clipper)]
        edge = q - p
        side = sign * (edge[0] * (out[:, 1] - p[1]) - edge[1] * (out[:, 0] - p[0]))
        kept = []
        for j in range(len(out)):
            a, b, sa, sb = out[j], out[(j + 1) % len(out)], side[j], side[(j + 1) % len(out)]
            if sa >= 0:
                kept.append(a)
            if (sa >= 0) != (sb >= 0):
                kept.append(a + (b - a) * (sa / (sa - sb)))
        out = np.array(kept).reshape(-1, 2)
    return out


def _signed(poly: np.ndarray) -> float:
    x, y = poly[:, 0], poly[:, 1]
    return float(x @ np.roll(y, -1) - y @ np.roll(x, -1))


def upright_iou(a: Cuboid, b: Cuboid, R: np.ndarray) -> float:
    """3D IoU of two upright boxes (one axis each along the up of the level frame ``R``): the overlap of
    their footprints times that of their heights, over the union of their volumes."""
    fa, lo_a, hi_a = _footprint(a, R)
    fb, lo_b, hi_b = _footprint(b, R)
    height = min(hi_a, hi_b) - max(lo_a, lo_b)
    if height <= 0:
        return 0.0
    common = _area(_clip(fa, fb)) * height
    union = _area(fa) * (hi_a - lo_a) + _area(fb) * (hi_b - lo_b) - common
    return common / union if union > 0 else 0.0


def agreed_objects(fits: list[list[SceneObject]], R: np.ndarray, need: int) -> list[SceneObject]:
    """The objects at least ``need`` of ``fits`` (each fit's objects, the first fit's first) hold a box of
    (module docstring), most points first. Each object of the first fit is looked at before the others',
    each fit's in the order of their score; an object takes from each other fit the box that overlaps it
    most among those not yet taken. ``R`` is the room's level frame."""
    pool = [(f, o) for f, objs in enumerate(fits) for o in objs]
    n = len(pool)
    iou = np.eye(n)
    for i in range(n):
        for j in range(i + 1, n):
            if pool[i][0] != pool[j][0]:
                iou[i, j] = iou[j, i] = upright_iou(pool[i][1].box, pool[j][1].box, R)
    taken = np.zeros(n, dtype=bool)
    kept = []
    for i in sorted(range(n), key=lambda i: (pool[i][0] != 0, -pool[i][1].score)):
        if taken[i]:
            continue
        members = [i]
        for f in range(len(fits)):
            if f == pool[i][0]:
                continue
            free = [j for j in range(n) if pool[j][0] == f and not taken[j] and iou[i, j] >= AGREE_IOU]
            if free:
                members.append(max(free, key=lambda j: iou[i, j]))
        if len(members) < need:
            continue
        taken[members] = True
        best = max(members, key=lambda j: float(iou[j, members].sum()))
        found = pool[best][1]
        # the cuboids that seeded it are the first fit's, the ones returned: none when that fit missed it
        own = [pool[j][1].cuboids for j in members if pool[j][0] == 0]
        share = len(members) / len(fits)
        kept.append(replace(found, score=found.score * share, cuboids=own[0] if own else ()))
    kept.sort(key=lambda o: -o.points)
    return kept

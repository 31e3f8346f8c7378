"""Seats side by side under one back: two chairs (or two table tops) that one group of a room's points took.

The grouping (:mod:`cuboidcli.fitting.objects`) grows each group from the inliers of one cuboid. Two
armchairs standing arm to arm have one back rest in a line, and the estimator often explains both backs
with one cuboid: its inliers touch, so they seed one group, which grows over both chairs. Their seats are
level slabs of one cuboid too, but with a gap between them they are separate pieces, so separate groups,
and both lie inside the backs' box (they would join it). When a group's box holds two or more such pieces
of one level slab cuboid, at least :data:`GAP_M` apart from each other, the group is the pieces' objects
together: its points are shared out to the nearest piece. A back alone, a thin group no longer than three
seats, with two or more such pieces touching its long side (:data:`BACK_LONG_M`) is shared out the same way:
two chairs whose backs one cuboid explains but whose seats stand in front of its box.

On the 10 real ScanNet scans (the saved fits of seeds 0-2 grouped again) the first case split the pair of
armchairs of scene0001_00 at each seed and nothing else (+1 chair matched at IoU 0.25, recall 59.1 / 60.4
/ 59.1 -> 59.7 / 61.1 / 59.7 %), the second two chairs of scene0001_01 at seeds 0-1 (+1 chair, 59.7 / 61.1
-> 60.4 / 61.7 %); the sequences rendered from them and the synthetic rooms kept their figures but for
one sequence's precision (docs/scenes.md).
"""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from cuboidcli.cuboid import Cuboid

#: A piece seeds this split when its cuboid is a level slab at most this thick (m) and tilted at most
#: :data:`SLAB_TILT_DEG` from level: a seat, a table top.
SLAB_M = 0.1
SLAB_TILT_DEG = 20.0
#: The pieces' footprints lie at least this far apart (m): two chairs' seats with their arms between them.
#: Two cushions of one sofa, or two pieces of one seat, touch (they were pieces for a gap under 2 voxels).
GAP_M = 0.1
#: A group that only stands beside its pieces is the backs of their seats when its footprint is at most
#: BACK_LONG_M long and at least BACK_ELONGATION times as long as it is deep, and the pieces come within
#: BACK_TOUCH_M of its long side (m). A 4 m kitchen run beside two table tops is no back.
BACK_LONG_M = 2.5
BACK_ELONGATION = 2.5
BACK_TOUCH_M = 0.07

Box = tuple[list[float], list[float], float]  # lo, hi (in a group's heading) and volume


def is_level_slab(c: Cuboid, up: np.ndarray) -> bool:
    """Whether cuboid ``c`` is a level slab (:data:`SLAB_M`, :data:`SLAB_TILT_DEG`) for the up direction
    ``up`` (3,)."""
    thin = int(np.argmin(c.half_size))
    level = abs(float(c.rotation[:, thin] @ up)) > math.cos(math.radians(SLAB_TILT_DEG))
    return 2.0 * float(c.half_size[thin]) <= SLAB_M and level


def _apart(a: Box, b: Box) -> bool:
    """Whether two boxes' footprints lie at least :data:`GAP_M` apart along one of their axes."""
    return any(min(a[1][k], b[1][k]) - max(a[0][k], b[0][k]) <= -GAP_M for k in (0, 1))


def _inside_share(inner: Box, outer: Box) -> float:
    """The share of ``inner``'s volume inside ``outer`` (both in one heading)."""
    common = 1.0
    for k in range(3):
        common *= max(min(outer[1][k], inner[1][k]) - max(outer[0][k], inner[0][k]), 0.0)
    return common / max(inner[2], 1e-12)


def _beside(piece: Box, back: Box, share: float) -> bool:
    """Whether ``piece`` lies along the long side of ``back`` (both in its heading; :data:`BACK_LONG_M`):
    ``share`` of its length within the back's and its footprint within :data:`BACK_TOUCH_M` of it."""
    sides = [back[1][k] - back[0][k] for k in (0, 1)]
    long_axis = int(sides[1] > sides[0])
    deep = 1 - long_axis
    if sides[long_axis] > BACK_LONG_M or sides[long_axis] < BACK_ELONGATION * sides[deep]:
        return False
    length = piece[1][long_axis] - piece[0][long_axis]
    along = min(back[1][long_axis], piece[1][long_axis]) - max(back[0][long_axis], piece[0][long_axis])
    gap = max(piece[0][deep] - back[1][deep], back[0][deep] - piece[1][deep])
    return along >= share * length and gap <= BACK_TOUCH_M and piece[1][2] > back[0][2]


def pieces_inside(
    a: int, groups: dict, seeds: list[int], slabs: set[int], box_of: Callable[[int, int], Box], share: float
) -> list[int]:
    """The groups that group ``a`` is made of when its box (``box_of(a, a)``) holds at least ``share`` of
    the boxes of two or more groups seeded by pieces of one level slab cuboid (``slabs``: the indices of
    such cuboids) other than ``a``'s own, lying apart, or when ``a`` is the back of two or more such pieces
    standing beside it (:func:`_beside`): the largest such set, or [] when there is none. ``box_of(g, h)``
    is group g's box in group h's heading."""
    if seeds[a] < 0:
        return []
    outer = box_of(a, a)
    for holds in (lambda b: _inside_share(b, outer) >= share, lambda b: _beside(b, outer, share)):
        found = _apart_pieces(a, groups, seeds, slabs, box_of, holds)
        if found:
            return found
    return []


def _apart_pieces(
    a: int, groups: dict, seeds: list[int], slabs: set[int], box_of: Callable[[int, int], Box], holds
) -> list[int]:
    """The largest set of two or more groups that ``holds`` takes (by their boxes in ``a``'s heading),
    seeded by pieces of one level slab other than ``a``'s cuboid, lying apart; [] when there is none."""
    by_cuboid: dict[int, list[int]] = {}
    for b in groups:
        if b != a and seeds[b] in slabs and seeds[b] != seeds[a] and holds(box_of(b, a)):
            by_cuboid.setdefault(seeds[b], []).append(b)
    best: list[int] = []
    for found in by_cuboid.values():
        boxes = [box_of(b, a) for b in found]
        pairs = ((i, j) for i in range(len(found)) for j in range(i + 1, len(found)))
        if len(found) > max(len(best), 1) and all(_apart(boxes[i], boxes[j]) for i, j in pairs):
            best = found
    return best


def nearest_piece(xy: np.ndarray, boxes: list[Box]) -> np.ndarray:
    """(N,) for each point ``xy`` (N, 2) (in the group's heading) the index of the box in ``boxes`` whose
    footprint is nearest (0 inside)."""
    dist = []
    for lo, hi, _ in boxes:
        out = np.maximum(np.maximum(np.asarray(lo[:2]) - xy, xy - np.asarray(hi[:2])), 0.0)
        dist.append(np.linalg.norm(out, axis=1))
    return np.argmin(np.array(dist), axis=0)

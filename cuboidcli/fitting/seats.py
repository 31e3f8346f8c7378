"""Seats side by side under one back: two chairs (or two table tops) that one group of a room's points took.

The grouping (:mod:`cuboidcli.fitting.objects`) grows each group from the inliers of one cuboid. Two
armchairs standing arm to arm have one back rest in a line, and the estimator often explains both backs
with one cuboid: its inliers touch, so they seed one group, which grows over both chairs. Their seats are
level slabs of one cuboid too, but with a gap between them they are separate pieces, so separate groups,
and both lie inside the backs' box (they would join it). When a group's box holds two or more such pieces
of one level slab cuboid, at least :data:`GAP_M` apart from each other, the group is the pieces' objects
together: its points are shared out to the nearest piece.

On the 10 real ScanNet scans (the saved fits of seeds 0-2 grouped again) it split the pair of armchairs of
scene0001_00 at each seed and nothing else (+1 chair matched at IoU 0.25, recall 59.1 / 60.4 / 59.1 ->
59.7 / 61.1 / 59.7 %); nothing in the sequences rendered from them or in the synthetic rooms
(docs/scenes.md).
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


def pieces_inside(
    a: int, groups: dict, seeds: list[int], slabs: set[int], box_of: Callable[[int, int], Box], share: float
) -> list[int]:
    """The groups that group ``a`` is made of when its box (``box_of(a, a)``) holds at least ``share`` of
    the boxes of two or more groups seeded by pieces of one level slab cuboid (``slabs``: the indices of
    such cuboids) other than ``a``'s own, lying apart: the largest such set, or [] when there is none.
    ``box_of(g, h)`` is group g's box in group h's heading."""
    if seeds[a] < 0:
        return []
    outer = box_of(a, a)
    by_cuboid: dict[int, list[int]] = {}
    for b in groups:
        if (
            b != a
            and seeds[b] in slabs
            and seeds[b] != seeds[a]
            and _inside_share(box_of(b, a), outer) >= share
        ):
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

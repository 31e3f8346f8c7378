"""A room's plan: the convex outline of its points seen from above, and how much of a box lies beyond it.

Numpy, float64. The outline is convex: a room of another shape (an L, a corridor off a room) is outlined
larger than it is, so a box is found beyond it less often, never more.
"""

from __future__ import annotations

import numpy as np

#: A box's volume is sampled on this many points along each of its axes.
SAMPLES = 11


def convex_hull_2d(points: np.ndarray) -> np.ndarray:
    """Convex hull of points (K, 2), counter-clockwise (positive cross products), without repeats: (P, 2)."""
    pts = np.unique(np.asarray(points, dtype=np.float64), axis=0)  # sorted by x, then y
    if len(pts) < 3:
        return pts

    def half(seq) -> list:
        chain: list = []
        for p in seq:
            while len(chain) >= 2:
                (ox, oy), (ax, ay) = chain[-2], chain[-1]
                if (ax - ox) * (p[1] - oy) - (ay - oy) * (p[0] - ox) > 0.0:
                    break
                chain.pop()
            chain.append(p)
        return chain

    lower, upper = half(pts), half(pts[::-1])
    return np.array(lower[:-1] + upper[:-1])


def inside_convex(poly: np.ndarray, xy: np.ndarray) -> np.ndarray:
    """(K,) bool: whether each point of ``xy`` (K, 2) lies inside or on the convex counter-clockwise
    polygon ``poly`` (P, 2), P >= 3."""
    inside = np.ones(len(xy), dtype=bool)
    for a, b in zip(poly, np.roll(poly, -1, axis=0), strict=True):
        inside &= (b[0] - a[0]) * (xy[:, 1] - a[1]) - (b[1] - a[1]) * (xy[:, 0] - a[0]) >= -1e-9
    return inside


#: The outline is the hull of the two points lying furthest out in each strip this wide (m) across the
#: room: within this of the hull of all the points, from a thousand of a scan's tens of thousands.
OUTLINE_CELL_M = 0.01


def room_outline(points: np.ndarray, level: np.ndarray) -> np.ndarray:
    """The convex outline (P, 2) of ``points`` (N, 3) seen from above: their hull in the first two axes of
    the level frame ``level`` (3, 3), whose columns are world axes, the third up. Only the first and last
    point along the second axis of each strip :data:`OUTLINE_CELL_M` wide along the first can lie on it (to
    within that width): a corner of the hull is the furthest point in some direction, and in its strip
    the first or last point lies at least as far in that direction, less the strip's width."""
    xy = np.asarray(points, dtype=np.float64) @ level[:, :2]
    if len(xy) == 0:
        return xy
    strip = np.floor(xy[:, 0] / OUTLINE_CELL_M).astype(np.int64)
    order = np.lexsort((xy[:, 1], strip))
    change = np.flatnonzero(strip[order][1:] != strip[order][:-1])
    ends = np.r_[0, change + 1, change, len(order) - 1]
    return convex_hull_2d(xy[order[ends]])


def share_beyond(
    center: np.ndarray, half: np.ndarray, rotation: np.ndarray, outline: np.ndarray, level: np.ndarray
) -> float:
    """The share of a box's volume (``center`` (3,), ``half`` (3,) sizes along the columns of ``rotation``
    (3, 3)) that lies beyond the ``outline`` (:func:`room_outline`, in the level frame ``level``) seen from
    above, from :data:`SAMPLES` points along each of its axes. 0 when the outline has no area (fewer than 3
    corners)."""
    if len(outline) < 3:
        return 0.0
    t = np.linspace(-1.0, 1.0, SAMPLES)
    grid = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)
    world = (grid * np.asarray(half)) @ np.asarray(rotation).T + np.asarray(center)
    return 1.0 - float(np.mean(inside_convex(outline, world @ level[:, :2])))

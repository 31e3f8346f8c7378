"""A room's plan: the convex outline of its points seen from above, and how much of a box lies beyond it.

Numpy, float64. The outline is convex: a room of another shape (an L, a corridor off a room) is outlined
larger than it is, so a box is found beyond it less often, never more.
"""

from __future__ import annotations

import numpy as np

from cuboidcli.cuboid import Cuboid

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


def room_outline(points: np.ndarray, level: np.ndarray) -> np.ndarray:
    """The convex outline (P, 2) of ``points`` (N, 3) seen from above: their hull in the first two axes of
    the level frame ``level`` (3, 3), whose columns are world axes, the third up (rounded to 1 mm, which
    spares the hull most of a scan's points)."""
    return convex_hull_2d(np.round(np.asarray(points, dtype=np.float64) @ level[:, :2], 3))


def share_beyond(box: Cuboid, outline: np.ndarray, level: np.ndarray) -> float:
    """The share of ``box``'s volume that lies beyond the ``outline`` (:func:`room_outline`, in the level
    frame ``level``) seen from above, from :data:`SAMPLES` points along each of its axes. 0 when the
    outline has no area (fewer than 3 corners)."""
    if len(outline) < 3:
        return 0.0
    t = np.linspace(-1.0, 1.0, SAMPLES)
    grid = np.stack(np.meshgrid(t, t, t, indexing="ij"), -1).reshape(-1, 3)
    world = (grid * box.half_size) @ box.rotation.T + box.center
    return 1.0 - float(np.mean(inside_convex(outline, world @ level[:, :2])))

"""Which side of a bare cloud's surfaces they were seen from: rays through an occupancy grid of the points
cross the room on the side it was scanned from and meet the furniture's other faces on the other."""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

#: One side of a surface is taken as its free side when its rays travel this share of their longest length
#: further than the other side's.
FREE_SIDE_MARGIN = 0.25


@njit(cache=True, parallel=True)
def _free_lengths(points, dirs, occupied, origin, cell, start_m, max_m, out):
    """For each point i and direction row d of ``dirs`` (N, D, 3): how far a ray from the point travels
    through unoccupied cells (from ``start_m`` on, at most ``max_m``); 0 when it leaves the grid first
    (beyond the scanned space nothing is known to be free)."""
    nx, ny, nz = occupied.shape
    step = 0.5 * cell
    for i in prange(points.shape[0]):
        for d in range(dirs.shape[1]):
            t = start_m
            length = max_m
            while t < max_m:
                x = points[i, 0] + t * dirs[i, d, 0]
                y = points[i, 1] + t * dirs[i, d, 1]
                z = points[i, 2] + t * dirs[i, d, 2]
                cx = int(math.floor((x - origin[0]) / cell))
                cy = int(math.floor((y - origin[1]) / cell))
                cz = int(math.floor((z - origin[2]) / cell))
                if cx < 0 or cy < 0 or cz < 0 or cx >= nx or cy >= ny or cz >= nz:
                    length = 0.0
                    break
                if occupied[cx, cy, cz]:
                    length = t
                    break
                t += step
            out[i, d] = length


def _cone(n: np.ndarray, angle_deg: float) -> np.ndarray:
    """(N, 5, 3): each unit normal and four directions tilted from it by ``angle_deg``."""
    helper = np.where(np.abs(n[:, :1]) < 0.9, np.array([[1.0, 0.0, 0.0]]), np.array([[0.0, 1.0, 0.0]]))
    u = np.cross(n, helper)
    u /= np.maximum(np.linalg.norm(u, axis=1, keepdims=True), 1e-12)
    v = np.cross(n, u)
    c, s = np.cos(np.deg2rad(angle_deg)), np.sin(np.deg2rad(angle_deg))
    return np.stack([n, c * n + s * u, c * n - s * u, c * n + s * v, c * n - s * v], axis=1)


def free_side_normals(
    points: np.ndarray,
    normals: np.ndarray,
    inside: np.ndarray,
    cell_m: float,
    max_m: float = 2.0,
    angle_deg: float = 30.0,
) -> np.ndarray:
    """Normals (N, 3) of a bare cloud turned to the side its surface was seen from: the side where rays
    (the normal and four directions ``angle_deg`` from it) travel further through empty cells of an
    occupancy grid of the points (cells of ``cell_m``) before they meet a surface, up to ``max_m``. From
    within a piece of furniture a ray meets its other faces within the furniture's size; from the room it
    crosses the room; a ray that leaves the scanned space counts as meeting a surface at once (behind a
    wall nothing is known to be free). Where both sides are alike (within a quarter of ``max_m``: a thin
    table top, a pillar), the normal is turned towards ``inside`` (3,), a point inside the room."""
    p = np.ascontiguousarray(points, dtype=np.float64)
    n = np.asarray(normals, dtype=np.float64)
    origin = p.min(0) - 2 * cell_m
    dims = np.ceil((p.max(0) + 2 * cell_m - origin) / cell_m).astype(np.int64) + 1
    occupied = np.zeros(tuple(int(d) for d in dims), dtype=np.bool_)
    idx = np.floor((p - origin) / cell_m).astype(np.int64)
    occupied[idx[:, 0], idx[:, 1], idx[:, 2]] = True
    toward = np.einsum("ij,ij->i", n, inside[None] - p) >= 0
    n = np.where(toward[:, None], n, -n)
    lengths = np.empty((2, len(p), 5))
    for k, sign in enumerate((1.0, -1.0)):
        dirs = np.ascontiguousarray(_cone(sign * n, angle_deg))
        _free_lengths(p, dirs, occupied, origin, float(cell_m), 2.0 * cell_m, float(max_m), lengths[k])
    front, back = lengths.mean(2)
    flip = back > front + FREE_SIDE_MARGIN * max_m
    return np.where(flip[:, None], -n, n)

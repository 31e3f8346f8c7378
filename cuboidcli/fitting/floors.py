"""The floor under each point of a room: the top face of the floor cuboid whose footprint is nearest to it.
Numpy, float64."""

from __future__ import annotations

import numpy as np

from cuboidcli.cuboid import Cuboid

#: A point's floor is the highest floor cuboid whose footprint comes this close to it (m), else the nearest
#: (the lowest instead lost one of 31 synthetic objects on the bare clouds).
FLOOR_REACH_M = 0.3


def floor_heights(level: np.ndarray, floors: list[Cuboid], R: np.ndarray) -> np.ndarray:
    """(N,) the height of the floor under each point of ``level`` (N, 3) (the room's level frame, ``R``
    turning it to the world): the top face of the floor cuboid whose footprint is nearest the point (the
    highest of those within :data:`FLOOR_REACH_M` of it). Real scans bend: one ScanNet room's floor
    (scene0001_00) rises 0.4 m over 3.5 m, and the room's highest floor cuboid hid the beds on the lower part
    (recall at IoU 0.25 on scenes 1-3: 43.7 -> 52.9 % seed 0, 42.0 -> 52.1 % seed 1)."""
    dist, height = [], []
    for c in floors:
        k = int(np.argmin(c.half_size))
        n = R.T @ c.rotation[:, k]
        n = n if n[2] >= 0 else -n
        top = R.T @ c.center + n * c.half_size[k]  # a point of the top face, level frame
        local = (level - R.T @ c.center) @ (R.T @ c.rotation)
        out = np.maximum(np.abs(local) - c.half_size, 0.0)
        out[:, k] = 0.0
        dist.append(np.linalg.norm(out, axis=1))
        nz = max(float(n[2]), 0.5)
        height.append(top[2] - (n[0] * (level[:, 0] - top[0]) + n[1] * (level[:, 1] - top[1])) / nz)
    dist, height = np.array(dist), np.array(height)
    near = dist <= np.maximum(dist.min(0), FLOOR_REACH_M)
    return np.where(near, height, -np.inf).max(0)

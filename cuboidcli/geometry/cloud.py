"""Unorganised points (a scanned or fused room, in its own world frame): voxel down-sampling, surface
normals, and the room's up direction and Manhattan axes.

A frame finds gravity from its image grid and the camera's own up (:mod:`cuboidcli.geometry.gravity`).
A room has neither: normals come from each point's neighbours in space, and the up axis is the axis of the
room's Manhattan frame nearest to a hint (the cameras' mean up for a sequence, the file format's
convention for a bare cloud: z up, y up for glTF), since floor, walls and ceiling alone do not say which
of their three directions is vertical.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from cuboidcli.geometry.gravity import manhattan_axes, manhattan_frame, refine_frame


def voxel_groups(points: np.ndarray, voxel_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Group points (N, 3) by cubic voxels of side ``voxel_m``: (mean point of each voxel (M, 3) float64,
    voxel of each point (N,) int64, first point of each voxel in input order (M,) int64). Voxels are
    ordered by their integer coordinates, so the result does not depend on the order of the input."""
    p = np.asarray(points, dtype=np.float64)
    cell = np.floor((p - p.min(0)) / voxel_m).astype(np.int64)
    dims = cell.max(0) + 1
    key = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
    _, first, inverse, counts = np.unique(key, return_index=True, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    sums = np.zeros((len(first), 3))
    np.add.at(sums, inverse, p)
    return sums / counts[:, None], inverse, first


def estimate_normals(points: np.ndarray, radius_m: float, max_nn: int = 24) -> np.ndarray:
    """Unit surface normals (N, 3) of points (N, 3) from their neighbours within ``radius_m`` (at most
    ``max_nn``), by Open3D's local PCA; signs are arbitrary (the Manhattan frame ignores them)."""
    import open3d as o3d

    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(np.asarray(points, dtype=np.float64)))
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=float(radius_m), max_nn=int(max_nn)))
    n = np.asarray(pcd.normals)
    norm = np.linalg.norm(n, axis=1, keepdims=True)
    return np.where(norm > 0, n / np.maximum(norm, 1e-12), 0.0)


@dataclass(frozen=True)
class RoomUp:
    """The up direction of a room and how it was found."""

    up: np.ndarray
    """(3,) unit, in the input's world frame."""
    axes: np.ndarray | None
    """(3, 3) the room's Manhattan axes (columns: up, two horizontal), or None when none was found."""
    source: str
    """"given", "estimated" (the Manhattan axis nearest the hint) or "hint" (no Manhattan frame found)."""
    support: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Share of the normals along each column of ``axes``."""

    def to_dict(self) -> dict:
        out = {"up": [round(float(v), 6) for v in self.up], "source": self.source}
        if self.axes is not None:
            out["manhattan_frame"] = [[round(float(v), 6) for v in row] for row in self.axes]
            out["support"] = [round(float(s), 4) for s in self.support]
        return out


def room_up(
    points: np.ndarray,
    normals: np.ndarray,
    hint: np.ndarray,
    given: np.ndarray | None = None,
    seed: int = 0,
    min_support: float = 0.05,
) -> RoomUp:
    """The room's up direction and axes from points (N, 3) and their normals (N, 3).

    ``given`` (3,) is used as it is (the room's horizontal axes are still estimated and made perpendicular
    to it). Otherwise the up axis is the Manhattan axis nearest to ``hint`` (3,), signed like it; it is
    trusted only when that axis carries at least ``min_support`` of the normals (floor, ceiling, tables)
    and lies within 45 degrees of the hint, else the hint itself is used."""
    hint = np.asarray(hint, dtype=np.float64)
    hint = hint / np.linalg.norm(hint)
    ok = np.linalg.norm(normals, axis=1) > 0.5
    frame = None
    support = np.zeros(3)
    try:
        frame, support = manhattan_frame(normals[ok], np.random.default_rng(seed))
        frame = refine_frame(points[ok], normals[ok], frame)
    except ValueError:
        frame = None
    if given is not None:
        up = np.asarray(given, dtype=np.float64)
        up = up / np.linalg.norm(up)
        axes = manhattan_axes(-up, _reorder(frame, up)) if frame is not None else None
        return RoomUp(up, axes, "given", _support(support, frame, up))
    if frame is None:
        return RoomUp(hint, None, "hint")
    k = int(np.abs(frame.T @ hint).argmax())
    up = frame[:, k] * np.sign(frame[:, k] @ hint)
    if support[k] < min_support or float(up @ hint) < np.cos(np.deg2rad(45.0)):
        return RoomUp(
            hint, manhattan_axes(-hint, _reorder(frame, hint)), "hint", _support(support, frame, hint)
        )
    return RoomUp(up, manhattan_axes(-up, _reorder(frame, up)), "estimated", _support(support, frame, up))


def _reorder(frame: np.ndarray, up: np.ndarray) -> np.ndarray:
    """The frame's columns with the one nearest ``up`` first (what :func:`manhattan_axes` expects)."""
    k = int(np.abs(frame.T @ up).argmax())
    others = [a for a in range(3) if a != k]
    return frame[:, [k, *others]]


def _support(support: np.ndarray, frame: np.ndarray | None, up: np.ndarray) -> tuple[float, float, float]:
    if frame is None:
        return (0.0, 0.0, 0.0)
    k = int(np.abs(frame.T @ up).argmax())
    others = [a for a in range(3) if a != k]
    return (float(support[k]), float(support[others[0]]), float(support[others[1]]))


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

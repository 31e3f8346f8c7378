"""Gravity and the room's Manhattan frame from a depth map.

Indoor scenes are built of surfaces along three orthogonal directions: the floor and the ceiling face up
or down, the walls and most furniture faces are vertical and, in most rooms, along two perpendicular
horizontal directions. Their normals therefore cluster around the six signed axes of one rotation, the
Manhattan frame. The frame is found by RANSAC over pairs of surface normals (two roughly perpendicular
normals define a frame; the frame that most normals agree with wins) and refined by averaging the normals
of each axis. The up direction is the frame axis closest to the camera's up (-y in OpenCV coordinates: a
hand-held or robot camera is rarely rolled or pitched by more than 45 degrees).

All vectors are in the OpenCV camera frame (x right, y down, z forward), metres.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

#: Up in the camera frame of a level camera (OpenCV: y points down).
CAMERA_UP = np.array([0.0, -1.0, 0.0])


@dataclass(frozen=True)
class Gravity:
    """The down direction and how it was obtained."""

    down: np.ndarray
    """(3,) unit vector in camera coordinates, pointing to the floor."""
    source: str
    """"estimated" (from the depth map) or "given" (by the user); a fitted frame's says which witness
    gave it (:func:`cuboidcli.geometry.down.combine_down`): "depth", "photo lines", "lines and depth"."""
    confidence: float
    """In [0, 1]: share of the surface normals that agree with the Manhattan frame, 0 when the estimate is
    not reliable; 1 for a given direction."""
    frame: np.ndarray | None = None
    """(3, 3) Manhattan frame (columns: up, then two horizontal axes), or None when not estimated."""
    support: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Share of the normals along each column of ``frame`` (either sign); from a photo's lines, the
    share of the segments' length."""
    lines_deg: float | None = None
    """Degrees between the down directions of the depth map and of the photo's lines, where both were
    estimated (their cross-check); None otherwise."""

    @property
    def up(self) -> np.ndarray:
        return -self.down

    def world_from_camera(self) -> np.ndarray:
        """(4, 4) camera -> gravity-aligned world: origin at the camera, z up, x the camera's x made
        horizontal (its heading), y = z x x. Rows 0-2 of the rotation are the world axes in camera
        coordinates."""
        m = np.eye(4)
        m[:3, :3] = level_frame(self.up).T
        return m

    def to_dict(self) -> dict:
        out = {
            "down": [round(float(x), 6) for x in self.down],
            "source": self.source,
            "confidence": round(float(self.confidence), 4),
        }
        if self.frame is not None:
            out["manhattan_frame"] = [[round(float(x), 6) for x in row] for row in self.frame]
            out["support"] = [round(float(s), 4) for s in self.support]
        if self.lines_deg is not None:
            out["lines_deg"] = round(float(self.lines_deg), 3)
        return out


def given_gravity(down) -> Gravity:
    """A user's down vector (from an IMU, ARKit, ...), normalised. Raises ValueError on a zero or non-finite
    vector."""
    v = np.asarray(down, dtype=np.float64).reshape(-1)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
        raise ValueError(f"gravity must be three finite numbers, not all zero (got {down!r})")
    return Gravity(down=v / np.linalg.norm(v), source="given", confidence=1.0)


def grid_normals(
    grid: np.ndarray, max_jump: float = 0.05, near_m: float = 2.5
) -> tuple[np.ndarray, np.ndarray]:
    """Surface normals of a back-projected grid (Hs, Ws, 3) (z = 0 where depth is missing).

    The normal at a cell is the cross product of the central differences to its neighbours s cells to the
    left/right and up/down, oriented towards the camera. Depth noise grows with the square of the depth,
    so the span s grows with it: 1 cell up to ``near_m``, 2 cells up to twice that, 3 beyond. Cells at
    depth edges (a neighbour's depth differs by more than ``max_jump`` times s times the cell's depth) or
    next to missing depth get no normal. Returns (normals (M, 3), flat cell indices (M,)).
    """
    hs, ws = grid.shape[:2]
    z = grid[..., 2]
    want = np.where(z < near_m, 1, np.where(z < 2 * near_m, 2, 3))
    normals = np.zeros((hs, ws, 3))
    ok_all = np.zeros((hs, ws), dtype=bool)
    for span in (1, 2, 3):
        c = (slice(span, hs - span), slice(span, ws - span))
        zc = z[c]
        nbs = (
            (slice(span, hs - span), slice(2 * span, ws)),
            (slice(span, hs - span), slice(0, ws - 2 * span)),
            (slice(2 * span, hs), slice(span, ws - span)),
            (slice(0, hs - 2 * span), slice(span, ws - span)),
        )
        ok = (zc > 0) & (want[c] == span)
        for nb in nbs:
            ok &= (z[nb] > 0) & (np.abs(z[nb] - zc) < max_jump * span * zc)
        n = np.cross(grid[nbs[0]] - grid[nbs[1]], grid[nbs[2]] - grid[nbs[3]])
        norm = np.linalg.norm(n, axis=-1)
        ok &= norm > 1e-12
        normals[c][ok] = n[ok] / norm[ok][:, None]
        ok_all[c] |= ok
    rows, cols = np.nonzero(ok_all)
    n = normals[rows, cols]
    p = grid[rows, cols]
    n *= -np.sign(np.sum(n * p, axis=1, keepdims=True) + 1e-12)  # towards the camera
    return n, rows * ws + cols


def _frame_from_pair(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    b = b - (b @ a) * a
    b /= np.linalg.norm(b)
    return np.stack([a, b, np.cross(a, b)], axis=1)


def _orthonormal(m: np.ndarray) -> np.ndarray:
    """The rotation nearest to m (polar decomposition; with weighted columns, the weighted Procrustes
    solution), columns kept in order."""
    u, _, vt = np.linalg.svd(m)
    r = u @ vt
    if np.linalg.det(r) < 0:
        u[:, -1] *= -1
        r = u @ vt
    return r


def manhattan_frame(
    normals: np.ndarray,
    rng: np.random.Generator,
    trials: int = 400,
    angle_deg: float = 8.0,
) -> tuple[np.ndarray, np.ndarray]:
    """The rotation whose signed axes most normals lie within ``angle_deg`` of.

    Returns (frame (3, 3) with unit columns, support (3,): share of the normals along each column, either
    sign). Raises ValueError for fewer than 20 normals.
    """
    n = len(normals)
    if n < 20:
        raise ValueError("too few surface normals for a Manhattan frame")
    cos_t = np.cos(np.deg2rad(angle_deg))
    sub = normals if n <= 3000 else normals[rng.choice(n, 3000, replace=False)]
    best, best_count = None, -1
    for _ in range(trials):
        i, j = rng.integers(0, len(sub), 2)
        if abs(sub[i] @ sub[j]) > np.sin(np.deg2rad(2 * angle_deg)):
            continue  # not perpendicular enough to define a frame
        f = _frame_from_pair(sub[i], sub[j])
        count = int((np.abs(sub @ f).max(1) > cos_t).sum())
        if count > best_count:
            best, best_count = f, count
    if best is None:
        raise ValueError("no two perpendicular surfaces in view")
    # refine: each axis becomes the mean of its (sign-aligned) normals, then re-orthonormalised
    for _ in range(3):
        dots = normals @ best
        k = np.abs(dots).argmax(1)
        hit = np.abs(dots).max(1) > cos_t
        cols = []
        for a in range(3):
            sel = hit & (k == a)
            if sel.sum() >= 3:
                m = (normals[sel] * np.sign(dots[sel, a])[:, None]).sum(0)
                cols.append(m / np.linalg.norm(m))
            else:
                cols.append(best[:, a])
        best = _orthonormal(np.stack(cols, axis=1))
    dots = np.abs(normals @ best)
    hit = dots.max(1) > cos_t
    k = dots.argmax(1)
    support = np.array([(hit & (k == a)).mean() for a in range(3)])
    return best, support


def estimate_gravity(
    grid: np.ndarray,
    seed: int = 0,
    min_support: float = 0.02,
    max_tilt_deg: float = 50.0,
) -> Gravity | None:
    """Gravity from a back-projected grid (Hs, Ws, 3) through the Manhattan frame of its surface normals.

    The frame is refined on its planes (:func:`refine_frame`); the up axis is its axis nearest the camera's
    up. The estimate is reliable (else None) when the up axis is within ``max_tilt_deg``
    of the camera's up and the frame is backed by the scene: the up axis has normals of its own (floor,
    ceiling, table tops: at least ``min_support`` of them, or a quarter of that next to a wall with
    ``min_support``), or both horizontal axes have half of ``min_support`` (two perpendicular walls fix
    the vertical as their common direction).
    """
    normals, idx = grid_normals(grid)
    rng = np.random.default_rng(seed)
    try:
        frame, support = manhattan_frame(normals, rng)
    except ValueError:
        return None
    frame = refine_frame(grid.reshape(-1, 3)[idx], normals, frame)
    k = int(np.abs(frame.T @ CAMERA_UP).argmax())
    up = frame[:, k] * np.sign(frame[:, k] @ CAMERA_UP)
    others = [a for a in range(3) if a != k]
    f = manhattan_axes(-up, frame[:, [k, others[0], others[1]]])
    sup = (float(support[k]), float(support[others[0]]), float(support[others[1]]))
    tilt = np.rad2deg(np.arccos(np.clip(up @ CAMERA_UP, -1.0, 1.0)))
    backed = (
        sup[0] >= min_support
        or (sup[0] >= 0.25 * min_support and max(sup[1:]) >= min_support)
        or min(sup[1:]) >= 0.5 * min_support
    )
    reliable = backed and tilt <= max_tilt_deg
    if not reliable:
        return None
    return Gravity(down=-up, source="estimated", confidence=float(sum(sup)), frame=f, support=sup)


def refine_axis(
    points: np.ndarray,
    normals: np.ndarray,
    axis: np.ndarray,
    angle_deg: float = 10.0,
    band_m: float = 0.03,
    min_share: float = 0.01,
    rounds: int = 3,
) -> tuple[np.ndarray, int]:
    """Refine one axis of the frame on the planes facing along it (for up: floor, table tops, ceiling).

    Normals from finite differences are noisy; the planes' points are not. Points whose normal is within
    ``angle_deg`` of the axis (either sign) are grouped by their offset along it into ``band_m`` slices;
    each slice that holds at least ``min_share`` of them is one plane. The common normal of those parallel
    planes is the smallest eigenvector of their pooled scatter (each plane about its own mean).
    Returns (the unit axis, sign kept; the number of plane points behind it, 0 = unchanged).
    """
    used = 0
    for _ in range(rounds):
        sel = np.abs(normals @ axis) > np.cos(np.deg2rad(angle_deg))
        if sel.sum() < 20:
            return axis, 0
        q = points[sel]
        h = q @ axis
        bins = np.floor((h - h.min()) / band_m).astype(np.int64)
        counts = np.bincount(bins)
        scatter = np.zeros((3, 3))
        used = 0
        for b in np.flatnonzero(counts >= max(min_share * len(q), 10)):
            # the plane: its slice and the two neighbouring ones, around the slice's mean offset
            pts = q[np.abs(h - h[bins == b].mean()) < band_m]
            d = pts - pts.mean(0)
            scatter += d.T @ d
            used += len(pts)
        if used < 20:
            return axis, 0
        new = np.linalg.eigh(scatter)[1][:, 0]
        new *= np.sign(new @ axis)
        if np.rad2deg(np.arccos(np.clip(new @ axis, -1.0, 1.0))) > angle_deg:
            return axis, 0  # the planes disagree with the frame: keep the frame's estimate
        axis = new
    return axis, used


def refine_frame(points: np.ndarray, normals: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """Refine every axis of a Manhattan frame on its planes (:func:`refine_axis`) and return the rotation
    nearest to them, each axis weighted by its number of plane points (weighted Procrustes)."""
    m = np.zeros((3, 3))
    for k in range(3):
        axis, used = refine_axis(points, normals, frame[:, k])
        m[:, k] = axis * max(used, 1)
    return _orthonormal(m)


def manhattan_axes(down: np.ndarray, frame: np.ndarray | None) -> np.ndarray | None:
    """The Manhattan frame made exactly vertical for ``down`` (columns: up, two horizontal axes), or None."""
    if frame is None:
        return None
    up = -down / np.linalg.norm(down)
    h = frame[:, 1] - (frame[:, 1] @ up) * up
    if np.linalg.norm(h) < 1e-6:
        h = frame[:, 2] - (frame[:, 2] @ up) * up
    h /= np.linalg.norm(h)
    return np.stack([up, h, np.cross(up, h)], axis=1)


def level_frame(up: np.ndarray) -> np.ndarray:
    """(3, 3) a gravity-aligned frame as columns in camera coordinates: x the camera's x made horizontal
    (its heading; the camera's z when x is vertical), y = z x x, z = up."""
    z = up / np.linalg.norm(up)
    x = np.array([1.0, 0.0, 0.0]) - z[0] * z
    if np.linalg.norm(x) < 1e-6:  # looking straight up or down the x axis: use the camera's z
        x = np.array([0.0, 0.0, 1.0]) - z[2] * z
    x /= np.linalg.norm(x)
    return np.stack([x, np.cross(z, x), z], 1)


def upright_rotation(rot: np.ndarray, up: np.ndarray) -> np.ndarray:
    """The rotation nearest to ``rot`` (3, 3; columns = a cuboid's axes) with one axis along ``up``: the
    axis most parallel to up is turned onto it (keeping its sign), the others are turned with it about
    the axis perpendicular to both; the cuboid keeps its yaw. Column order and handedness are kept."""
    k = int(np.abs(rot.T @ up).argmax())
    target = up * np.sign(rot[:, k] @ up)
    return smallest_rotation(rot[:, k], target) @ rot


def smallest_rotation(src: np.ndarray, dst: np.ndarray) -> np.ndarray:
    """(3, 3) the smallest rotation taking unit vector src onto unit vector dst (Rodrigues). For opposite
    vectors it is the half turn about the axis perpendicular to src and to z (or to x when src is along z).
    """
    v = np.cross(src, dst)
    s, c = float(np.linalg.norm(v)), float(src @ dst)
    if s < 1e-12:
        if c > 0:
            return np.eye(3)
        n = np.cross(src, [0.0, 0.0, 1.0])
        if np.linalg.norm(n) < 1e-6:
            n = np.cross(src, [1.0, 0.0, 0.0])
        n /= np.linalg.norm(n)
        return 2.0 * np.outer(n, n) - np.eye(3)
    kx = np.array([[0, -v[2], v[1]], [v[2], 0, -v[0]], [-v[1], v[0], 0]]) / s
    return np.eye(3) + s * kx + (1 - c) * kx @ kx


def manhattan_rotation(rot: np.ndarray, axes: np.ndarray, first: int = -1) -> np.ndarray:
    """The Manhattan-aligned rotation nearest to ``rot``: each of rot's columns becomes the signed axis of
    ``axes`` (3, 3) closest to it (a permutation with signs), handedness kept. Columns are matched most
    certain first, except that column ``first`` (>= 0: a slab's normal) is matched before all others."""
    dots = rot.T @ axes  # (cuboid axis, room axis)
    out = np.zeros((3, 3))
    used: set[int] = set()
    order = [int(i) for i in np.argsort(-np.abs(dots).max(1))]  # most certain cuboid axis first
    if first >= 0:
        order = [first] + [i for i in order if i != first]
    for i in order:
        j = max((j for j in range(3) if j not in used), key=lambda j: abs(dots[i, j]))
        used.add(j)
        out[:, i] = axes[:, j] * (1.0 if dots[i, j] >= 0 else -1.0)
    if np.linalg.det(out) < 0:
        out[:, int(np.abs(dots).max(1).argmin())] *= -1
    return out

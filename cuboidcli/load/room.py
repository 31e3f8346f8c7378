"""Loading a room: a point cloud or mesh file, a posed RGB-D sequence folder (fused here,
:mod:`cuboidcli.load.fuse`), or points already in memory (an (N, 3[+3]) array, an Open3D point cloud),
each in its own world frame, metres (a file's coordinates scaled by its ``--unit``; every room checked to
be room-sized: :mod:`cuboidcli.load.units`). What the input says about up (the cameras' mean up, y for
glTF, z otherwise) is the hint the room's up direction is estimated near; ``--up`` (:func:`parse_up`) gives
it."""

from __future__ import annotations

import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.io.depth import InputError
from cuboidcli.io.scan import PointCloud, is_scan_file, read_scan
from cuboidcli.io.sequence import Sequence, read_sequence, sequence_layout
from cuboidcli.load.units import check_cloud, check_unit, in_metres

#: Up directions by name for ``--up``.
UP_NAMES = {"z": (0.0, 0.0, 1.0), "y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0), "x": (1.0, 0.0, 0.0)}
#: A cuboid is seen by a frame when at least this many of its inliers were observed from that frame.
SEEN_MIN_POINTS = 10
#: Side of the voxels a sequence's frames are fused into (m), finer than the fitting voxels.
FUSE_VOXEL_M = 0.02
#: The up a bare cloud is taken to have, unless its format says otherwise (glTF: y).
Z_UP = np.array([0.0, 0.0, 1.0])


def parse_up(text: str | None) -> tuple[float, float, float] | None:
    """``z``, ``y``, ``-y``, ``x`` or ``x,y,z`` (any length, not zero) -> a unit 3-tuple; None stays None.
    Raises InputError for anything else."""
    if text is None:
        return None
    t = text.strip().lower()
    if t in UP_NAMES:
        return UP_NAMES[t]
    try:
        v = np.array([float(x) for x in t.split(",")])
    except ValueError:
        v = np.zeros(0)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
        raise InputError(f"--up {text!r}: give z, y, -y, x or three numbers x,y,z (not all zero)")
    return tuple(float(x) for x in v / np.linalg.norm(v))


def is_room_input(path: str | Path) -> bool:
    """Whether ``path`` is a room: a point cloud or mesh file, or a folder laid out as a posed sequence."""
    p = Path(path)
    if p.is_dir():
        return sequence_layout(p) is not None
    return is_scan_file(p) and p.suffix.lower() not in (".npy", ".npz") or _is_point_array(p)


def _is_point_array(p: Path) -> bool:
    """An .npy/.npz file of points (N, 3) or (N, 6), not a depth map (H, W)."""
    if p.suffix.lower() not in (".npy", ".npz") or not p.is_file():
        return False
    try:
        if p.suffix.lower() == ".npy":
            a = np.load(p, mmap_mode="r", allow_pickle=False)
            return a.ndim == 2 and a.shape[1] in (3, 6) and a.shape[0] > 6
        with np.load(p, allow_pickle=False) as z:
            return any(k in z.files for k in ("points", "xyz"))
    except (OSError, ValueError):
        return False


@dataclass
class RoomData:
    """A room ready to fit: its points in their own world frame and what is known about how they were
    seen."""

    cloud: PointCloud
    sequence: Sequence | None
    up_hint: np.ndarray
    """(3,) the direction the input calls up: the cameras' mean up, y for glTF, else z."""
    load_seconds: float
    meta: dict = field(default_factory=dict)
    """The result's ``input`` entry."""

    @property
    def camera(self) -> Camera | None:
        """A sequence's depth camera; None for a bare cloud, which no camera saw."""
        return None if self.sequence is None else self.sequence.camera


def load_room(
    path: str | Path,
    *,
    unit: str = "m",
    every: int = 1,
    intrinsics: str | None = None,
    depth_scale: float | None = None,
    progress=None,
) -> RoomData:
    """Read a scan file, its coordinates in ``unit`` (m, cm, mm), or fuse a sequence folder (every
    ``every``-th frame; ``intrinsics`` (``-K`` or a ``--camera`` preset) and ``depth_scale`` override the
    folder's). ``progress(done, total)`` follows the fusion. Raises InputError (one line) for unusable
    input."""
    from cuboidcli.load.fuse import fuse_sequence

    p = Path(path)
    if not p.exists():
        raise InputError(f"not found: {p}")
    if every < 1:
        raise InputError(f"--every must be at least 1 (got {every})")
    t = time.perf_counter()
    if p.is_dir():
        seq = read_sequence(p, every=every, intrinsics=intrinsics, depth_scale=depth_scale)
        cloud = fuse_sequence(seq, voxel_m=FUSE_VOXEL_M, progress=progress)
        cloud.warnings = [*seq.warnings, *cloud.warnings]
        ups = np.stack([f.world_from_camera[:3, :3] @ np.array([0.0, -1.0, 0.0]) for f in seq.frames])
        hint = ups.mean(0)
        if np.linalg.norm(hint) < 1e-6:
            hint = Z_UP
        return _room(path, cloud, seq, hint / np.linalg.norm(hint), time.perf_counter() - t)
    check_unit(unit)  # before a large file is read
    cloud = in_metres(read_scan(p), unit)
    hint = np.array([0.0, 1.0, 0.0]) if p.suffix.lower() in (".glb", ".gltf") else Z_UP
    return _room(path, cloud, None, hint, time.perf_counter() - t)


def points_room(points, colors=None) -> RoomData:
    """A room given in memory: an (N, 3) array of points in metres, an (N, 6) array of points and colours
    (0-255), or an Open3D point cloud; z is taken as up unless ``--up`` says otherwise. Raises
    InputError for unusable points."""
    t = time.perf_counter()
    if hasattr(points, "points") and not isinstance(points, np.ndarray):  # an Open3D PointCloud
        o3d_cloud = points
        points = np.asarray(o3d_cloud.points)
        if colors is None and o3d_cloud.has_colors():
            colors = np.asarray(o3d_cloud.colors) * 255.0
    points = np.asarray(points)
    if points.ndim != 2 or points.shape[1] not in (3, 6) or not np.issubdtype(points.dtype, np.number):
        raise InputError(
            f"points must be an (N, 3) or (N, 6) array of numbers, got {points.shape} {points.dtype}"
        )
    if points.shape[1] == 6:
        points, colors = points[:, :3], points[:, 3:] if colors is None else colors
    if colors is not None:
        colors = np.clip(np.round(np.asarray(colors, dtype=np.float64)), 0, 255).astype(np.uint8)
    cloud = PointCloud(
        np.asarray(points, dtype=np.float64), colors, meta={"path": "array", "format": "array"}
    )
    cloud = check_cloud(cloud, "m")
    return _room(None, cloud, None, Z_UP, time.perf_counter() - t)


def _room(path, cloud: PointCloud, seq: Sequence | None, hint: np.ndarray, seconds: float) -> RoomData:
    meta = {
        "path": None if path is None else str(path),
        **{k: v for k, v in cloud.meta.items() if k != "path"},
        "n_points": int(len(cloud.points)),
        "load_s": round(seconds, 6),
        "warnings": list(cloud.warnings),
    }
    return RoomData(cloud, seq, hint, seconds, meta)


def world_from_input(up: np.ndarray, axes: np.ndarray | None) -> np.ndarray:
    """(4, 4) the input's frame -> a levelled world: z along ``up``, x and y along the room's horizontal
    axes when known (else the input's x made horizontal); no translation."""
    z = np.asarray(up, dtype=np.float64)
    z = z / np.linalg.norm(z)
    if axes is not None:
        x = axes[:, 1] - (axes[:, 1] @ z) * z
    else:
        x = np.array([1.0, 0.0, 0.0]) - z[0] * z
        if np.linalg.norm(x) < 1e-6:
            x = np.array([0.0, 1.0, 0.0]) - z[1] * z
    x = x / np.linalg.norm(x)
    m = np.eye(4)
    m[:3, :3] = np.stack([x, np.cross(z, x), z])
    return m


def seen_by(cloud: PointCloud, labels: np.ndarray, n_cuboids: int) -> list[list[str]]:
    """Per cuboid, the names of the frames that observed at least :data:`SEEN_MIN_POINTS` of its inlier
    points (in the fused cloud, each point keeps one observing frame)."""
    if cloud.frames is None or not cloud.frame_names:
        return [[] for _ in range(n_cuboids)]
    out = []
    for k in range(n_cuboids):
        counts = np.bincount(cloud.frames[labels == k], minlength=len(cloud.frame_names))
        out.append([cloud.frame_names[i] for i in np.flatnonzero(counts >= SEEN_MIN_POINTS)])
    return out

"""Posed RGB-D sequence folders (TUM, ScanNet export, Redwood, plain) and their fusion into one cloud.

Poses are camera-to-world 4x4 transforms with OpenCV camera axes (x right, y down, z forward), metres.
Every problem raises :class:`InputError` with a one-line message.
"""

from __future__ import annotations

import json
import math
import os
import re
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cuboidcli.camera import PRESETS, Camera, valid_depth
from cuboidcli.io import depth as depth_io
from cuboidcli.io.depth import InputError, parse_intrinsics
from cuboidcli.io.scan import PointCloud, check_cloud

LAYOUTS = ("tum", "scannet", "redwood", "plain")
LAYOUT_NEEDS = (
    "TUM (rgb.txt, depth.txt, groundtruth.txt), ScanNet (depth/, pose/, intrinsic/intrinsic_depth.txt), "
    "Redwood (depth/, color/, a *.log trajectory, a camera .json) or plain (depth/, pose/, cameras.json)"
)
#: Largest time difference (s) between a TUM depth frame and its pose or RGB image.
TUM_MAX_DT = 0.02
#: Tolerance of a rotation's orthonormality, |R^T R - I|.
RIGID_TOL = 1e-3
#: Pixels back-projected per frame at most: larger frames take every k-th pixel.
MAX_POINTS_PER_FRAME = 80_000
#: Voxel indices run over [-_HALF, _HALF) per axis, 21 bits each in one int64 key.
_HALF = 1 << 20


@dataclass
class SequenceFrame:
    """One depth frame; ``world_from_camera`` (4, 4) float64 camera-to-world, OpenCV axes, metres."""

    name: str
    depth_path: Path
    rgb_path: Path | None
    world_from_camera: np.ndarray


@dataclass
class Sequence:
    """A posed RGB-D sequence; ``camera`` is the depth camera (with its size), ``depth_scale`` metres per
    depth-PNG unit."""

    root: Path
    layout: str
    frames: list[SequenceFrame]
    camera: Camera
    depth_scale: float
    warnings: list[str] = field(default_factory=list)


def _name_key(path: Path) -> tuple:
    """Sort key: numbers inside names compare as numbers (ScanNet's 2.png before 10.png)."""
    return tuple((0, int(t), "") if t.isdigit() else (1, 0, t) for t in re.split(r"(\d+)", path.stem) if t)


def _depth_files(root: Path) -> list[Path]:
    return sorted((p for p in (root / "depth").iterdir() if p.suffix.lower() == ".png"), key=_name_key)


def _log_file(root: Path) -> Path | None:
    logs = sorted(root.glob("*.log"))
    return root / "trajectory.log" if root / "trajectory.log" in logs else logs[0] if len(logs) == 1 else None


def sequence_layout(path: str | os.PathLike) -> str | None:
    """Which layout of :data:`LAYOUTS` the folder ``path`` is, or None when it is not a sequence."""
    root = Path(path)
    if (root / "depth.txt").is_file() and (root / "groundtruth.txt").is_file():
        return "tum"
    if not (root / "depth").is_dir():
        return None
    if (root / "pose").is_dir() and (root / "intrinsic" / "intrinsic_depth.txt").is_file():
        return "scannet"
    if (root / "pose").is_dir() and (root / "cameras.json").is_file():
        return "plain"
    return "redwood" if _log_file(root) is not None else None


def check_pose(matrix: np.ndarray, where: str) -> np.ndarray:
    """``matrix`` as a (4, 4) float64 rigid transform; InputError naming ``where`` otherwise."""
    m = np.asarray(matrix, dtype=np.float64)
    if m.shape != (4, 4) or not np.isfinite(m).all():
        raise InputError(f"{where}: a pose must be a 4x4 matrix of finite numbers (camera-to-world)")
    rot = m[:3, :3]
    err = float(np.abs(rot.T @ rot - np.eye(3)).max())
    if err > RIGID_TOL or np.linalg.det(rot) < 0 or np.abs(m[3] - [0, 0, 0, 1]).max() > RIGID_TOL:
        raise InputError(
            f"{where}: the pose is not a rigid transform (|R^T R - I| = {err:.3g}, det R = "
            f"{np.linalg.det(rot):.3g}, last row {m[3].tolist()}); give [R t; 0 0 0 1] with R a rotation"
        )
    return m


def _read_matrix(path: Path) -> np.ndarray:
    try:
        values = np.loadtxt(path, dtype=np.float64, ndmin=1).ravel()
    except (ValueError, OSError) as e:
        raise InputError(f"{path}: not a 4x4 matrix of numbers ({' '.join(str(e).split())})") from e
    if values.size != 16:
        raise InputError(f"{path}: a 4x4 matrix is expected, got {values.size} numbers")
    return values.reshape(4, 4)


def _table(path: Path, columns: int) -> list[list[str]]:
    """Rows of a TUM text file sorted by their timestamp (``#`` comments skipped)."""
    lines = path.read_text(encoding="utf-8", errors="replace").splitlines()
    rows = [r for r in map(str.split, lines) if r and not r[0].startswith("#")]
    try:
        if any(len(r) < columns for r in rows):
            raise ValueError(f"a line has fewer than {columns} fields")
        return sorted(rows, key=lambda r: float(r[0]))
    except ValueError as e:
        raise InputError(f"{path}: each line must be a timestamp and {columns - 1} more fields ({e})") from e


def _nearest(times: np.ndarray, query: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """For each of ``query`` (N,) the index into sorted ``times`` (M,) nearest to it and the gap in seconds
    (inf when ``times`` is empty)."""
    if not len(times):
        return np.zeros(len(query), dtype=int), np.full(len(query), np.inf)
    hi = np.searchsorted(times, query).clip(0, len(times) - 1)
    lo = (hi - 1).clip(0)
    best = np.where(np.abs(times[lo] - query) <= np.abs(times[hi] - query), lo, hi)
    return best, np.abs(times[best] - query)


def _read_tum(root: Path, notes: list[str]) -> tuple[list[SequenceFrame], Camera | None]:
    import trimesh.transformations as tf

    depth = _table(root / "depth.txt", 2)
    truth = _table(root / "groundtruth.txt", 8)
    rgb = _table(root / "rgb.txt", 2) if (root / "rgb.txt").is_file() else []
    try:
        poses = np.array([r[:8] for r in truth], dtype=np.float64).reshape(-1, 8)
    except ValueError as e:
        raise InputError(f"{root}/groundtruth.txt: lines must be 'timestamp tx ty tz qx qy qz qw'") from e
    depth_t = np.array([float(r[0]) for r in depth])
    k, dt = _nearest(poses[:, 0], depth_t)
    j, dt_rgb = _nearest(np.array([float(r[0]) for r in rgb]), depth_t)
    frames = []
    for i in np.flatnonzero(dt <= TUM_MAX_DT):
        t, (qx, qy, qz, qw) = poses[k[i], 1:4], poses[k[i], 4:]
        if not abs(math.hypot(qx, qy, qz, qw) - 1.0) < 1e-2:
            raise InputError(f"groundtruth.txt at {truth[k[i]][0]}: the quaternion is not of unit length")
        pose = tf.quaternion_matrix([qw, qx, qy, qz])
        pose[:3, 3] = t
        rgb_path = root / rgb[j[i]][1] if dt_rgb[i] <= TUM_MAX_DT else None
        frames.append(SequenceFrame(depth[i][0], root / depth[i][1], rgb_path, pose))
    if len(frames) < len(depth):
        dropped = len(depth) - len(frames)
        notes.append(f"dropped {dropped} of {len(depth)} depth frames without a pose within {TUM_MAX_DT} s")
    if not frames and depth:
        raise InputError(f"none of the {len(depth)} depth frames has a pose within {TUM_MAX_DT} s in {root}")
    return frames, parse_intrinsics(None, "tum")


def _color_for(root: Path, stem: str) -> Path | None:
    return next((p for s in (".jpg", ".png", ".jpeg") if (p := root / "color" / (stem + s)).is_file()), None)


def _posed_files(root: Path, notes: list[str], skip_nonfinite: bool) -> list[SequenceFrame]:
    """Frames of depth/<name>.png with pose/<name>.txt (ScanNet and plain)."""
    depth = _depth_files(root)
    missing = [p for p in depth if not (root / "pose" / (p.stem + ".txt")).is_file()]
    if missing:
        raise InputError(
            f"{len(missing)} of {len(depth)} depth frames have no pose file (first: {missing[0].name} needs "
            f"pose/{missing[0].stem}.txt); every depth frame needs a 4x4 camera-to-world pose"
        )
    frames = []
    for p in depth:
        matrix = _read_matrix(root / "pose" / (p.stem + ".txt"))
        if skip_nonfinite and not np.isfinite(matrix).all():
            continue  # ScanNet marks frames where its tracking failed with inf poses
        pose = check_pose(matrix, f"pose/{p.stem}.txt")
        frames.append(SequenceFrame(p.stem, p, _color_for(root, p.stem), pose))
    if skipped := len(depth) - len(frames):
        notes.append(f"skipped {skipped} of {len(depth)} frames with invalid (inf/NaN) poses")
    return frames


def _read_scannet(root: Path, notes: list[str]) -> tuple[list[SequenceFrame], Camera | None]:
    frames = _posed_files(root, notes, skip_nonfinite=True)
    k = _read_matrix(root / "intrinsic" / "intrinsic_depth.txt")
    return frames, Camera(k[0, 0], k[1, 1], k[0, 2], k[1, 2], depth_scale=0.001, source="intrinsic_depth.txt")


def _read_plain(root: Path, notes: list[str]) -> tuple[list[SequenceFrame], Camera | None]:
    intr = parse_intrinsics(str(root / "cameras.json"))
    return _posed_files(root, notes, skip_nonfinite=False), intr


def _read_redwood(root: Path, notes: list[str]) -> tuple[list[SequenceFrame], Camera | None]:
    log = _log_file(root)
    try:  # blocks of a line 'i j n' and the 4x4 matrix: 19 numbers each
        blocks = np.array(log.read_text(encoding="utf-8", errors="replace").split(), dtype=np.float64)
        blocks = blocks.reshape(-1, 19)
    except ValueError as e:
        raise InputError(f"{log}: a Redwood trajectory is blocks of a line 'i i n' and a 4x4 matrix") from e
    poses = [check_pose(b[3:].reshape(4, 4), f"{log.name} pose {i}") for i, b in enumerate(blocks)]
    depth = _depth_files(root)
    if len(poses) < len(depth):
        raise InputError(
            f"{len(depth) - len(poses)} of {len(depth)} depth frames have no pose in {log.name} "
            f"(first: {depth[len(poses)].name}); it needs one 4x4 pose per depth frame"
        )
    if len(poses) > len(depth):
        notes.append(f"{log.name} has {len(poses)} poses for {len(depth)} depth frames; extra poses ignored")
    frames = [SequenceFrame(p.stem, p, _color_for(root, p.stem), poses[i]) for i, p in enumerate(depth)]
    for js in sorted(root.glob("*.json")):
        try:
            d = json.loads(js.read_text(encoding="utf-8"))
            k = np.array(d["intrinsic_matrix"], dtype=np.float64).reshape(3, 3).T  # stored column-major
            size = (int(d["width"]), int(d["height"])) if "width" in d else (0, 0)
        except (ValueError, TypeError, KeyError, IndexError, UnicodeDecodeError):
            continue  # not an Open3D camera file
        return frames, Camera(k[0, 0], k[1, 1], k[0, 2], k[1, 2], *size, d.get("depth_scale"), str(js))
    return frames, None


def _png_size(path: Path) -> tuple[int, int] | None:
    """(width, height) from a PNG's header, without decoding it; None when it is not a readable PNG."""
    try:
        with path.open("rb") as f:
            head = f.read(24)
    except OSError:
        return None
    if len(head) < 24 or not head.startswith(b"\x89PNG\r\n\x1a\n") or head[12:16] != b"IHDR":
        return None
    return int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")


def read_sequence(
    path: str | os.PathLike, every: int = 1, intrinsics: str | None = None, depth_scale: float | None = None
) -> Sequence:
    """The posed frames of a sequence folder, every ``every``-th kept.

    ``intrinsics`` (``fx,fy,cx,cy``, a JSON file or a preset name, as ``-K``) and ``depth_scale`` (metres
    per depth-PNG unit) override the folder's own.
    """
    root = Path(path)
    if not root.exists():
        raise InputError(f"sequence folder not found: {root}")
    layout = sequence_layout(root)
    if layout is None:
        raise InputError(f"{root} is not an RGB-D sequence folder; give one of: {LAYOUT_NEEDS}")
    if not (isinstance(every, int) and every >= 1):
        raise InputError(f"every = {every!r}: give a whole number >= 1 (1 keeps every frame)")
    if depth_scale is not None and not (math.isfinite(depth_scale) and depth_scale > 0):
        raise InputError(f"depth scale {depth_scale} must be a positive number of metres per depth unit")
    notes: list[str] = []
    readers = {"tum": _read_tum, "scannet": _read_scannet, "redwood": _read_redwood, "plain": _read_plain}
    frames, intr = readers[layout](root, notes)
    layout_scale = intr.depth_scale if intr is not None else None
    if intrinsics is not None:
        intr = parse_intrinsics(None, intrinsics) if intrinsics in PRESETS else parse_intrinsics(intrinsics)
    if intr is None:
        raise InputError(f"{root} has no camera .json with an intrinsic_matrix; pass -K fx,fy,cx,cy")
    frames = frames[::every]
    if not frames:
        raise InputError(f"{root} ({layout}) has no depth frames with poses; add depth images and poses")
    # Unreadable images have no size here; fusion skips them with a count.
    sizes = [(f.depth_path.name, s) for f in frames if (s := _png_size(f.depth_path)) is not None]
    if not sizes:
        raise InputError(f"none of the {len(frames)} depth images in {root} is a readable PNG")
    (name0, size), odd = sizes[0], [(n, s) for n, s in sizes if s != sizes[0][1]]
    if odd:
        raise InputError(
            f"depth frames differ in size: {odd[0][0]} is {odd[0][1][0]}x{odd[0][1][1]} but {name0} is "
            f"{size[0]}x{size[1]}; all frames must be the same size"
        )
    if intr.source.startswith("preset:"):
        intr = depth_io.intrinsics_for_size(intr, *size, preset=intr.source.split(":", 1)[1])
    elif intr.sized and (intr.width, intr.height) != size:
        raise InputError(
            f"the intrinsics ({intr.source}) are for {intr.width}x{intr.height} images but the depth frames "
            f"are {size[0]}x{size[1]}; give intrinsics for the depth camera with -K"
        )
    if depth_scale is None:
        depth_scale = next((d for d in (intr.depth_scale, layout_scale) if d is not None), 0.001)
    camera = Camera(float(intr.fx), float(intr.fy), float(intr.cx), float(intr.cy), *size)
    return Sequence(root, layout, frames, camera, float(depth_scale), notes)


def _reduce(keys, sums, counts, csums, ccounts, dists, frames):
    """Merge rows that share a voxel key: sums add up, the observation nearest to the voxel centre stays
    (on a tie the earlier row, i.e. the earlier frame: a stable sort keeps the result deterministic)."""
    order = np.argsort(keys, kind="stable")
    keys, dists = keys[order], dists[order]
    starts = np.flatnonzero(np.r_[True, keys[1:] != keys[:-1]])
    group = np.repeat(np.arange(len(starts)), np.diff(np.r_[starts, len(keys)]))
    nearest = np.flatnonzero(dists == np.minimum.reduceat(dists, starts)[group])
    nearest = nearest[np.r_[True, group[nearest][1:] != group[nearest][:-1]]]
    summed = (np.add.reduceat(v[order], starts, axis=0) for v in (sums, counts, csums, ccounts))
    return keys[starts], *summed, dists[nearest], frames[order[nearest]]


def _frame_rows(seq: Sequence, k: int, step: int, voxel_m: float, max_depth_m: float) -> tuple | str:
    """Frame ``k``'s valid depth as rows for :func:`_reduce` (voxel key, world point, count 1, colour,
    colour count, distance of the voxel centre to the camera, frame); why not when it is unreadable."""
    frame, cam = seq.frames[k], seq.camera
    try:
        depth = depth_io.read_depth(frame.depth_path, seq.depth_scale)
    except InputError as e:
        return str(e)
    if depth.shape != (cam.height, cam.width):  # its PNG header said otherwise: a corrupt file
        return f"{frame.depth_path.name} is {depth.shape[1]}x{depth.shape[0]}, not {cam.width}x{cam.height}"
    grid = depth[::step, ::step]
    ok = valid_depth(grid) & (grid <= max_depth_m)
    pose = frame.world_from_camera
    pts = cam.backproject_grid(grid, step)[ok] @ pose[:3, :3].T + pose[:3, 3]
    idx = np.floor(pts / voxel_m).astype(np.int64)
    if len(idx) and np.abs(idx).max() >= _HALF:
        raise InputError(f"{frame.name}: points lie {np.abs(pts).max():.0f} m away; are the poses in metres?")
    key = ((idx[:, 0] + _HALF) << 42) | ((idx[:, 1] + _HALF) << 21) | (idx[:, 2] + _HALF)
    dist = np.linalg.norm((idx + 0.5) * voxel_m - pose[:3, 3], axis=1)
    rgb = _frame_rgb(frame, cam)
    cols = np.zeros((len(pts), 3)) if rgb is None else rgb[::step, ::step][ok].astype(np.float64)
    ones, has = np.ones(len(pts)), np.full(len(pts), float(rgb is not None))
    return key, pts, ones, cols, has, dist, np.full(len(pts), k, np.int32)


def _frame_rgb(frame: SequenceFrame, cam: Camera) -> np.ndarray | None:
    """The frame's colour image (H, W, 3) uint8 at the depth size (a colour camera of another resolution is
    taken as registered to the depth camera), or None when it has none or it is unreadable."""
    try:
        rgb = None if frame.rgb_path is None else depth_io.read_rgb(frame.rgb_path)
    except InputError:
        return None
    if rgb is not None and rgb.shape[:2] != (cam.height, cam.width):
        import cv2

        rgb = cv2.resize(rgb, (cam.width, cam.height), interpolation=cv2.INTER_AREA)
    return rgb


def fuse_sequence(
    seq: Sequence,
    voxel_m: float = 0.02,
    max_depth_m: float = 6.0,
    progress: Callable[[int, int], None] | None = None,
    unit_check: bool = True,
) -> PointCloud:
    """All frames' depth back-projected into the world frame and averaged per ``voxel_m`` voxel.

    Depth 0 (holes) and beyond ``max_depth_m`` is ignored. A point's colour is the mean of the voxel's
    observations that have colour; its viewpoint and frame are those of the observation whose camera is
    nearest to the voxel's centre. Frames whose depth cannot be read are skipped with a warning. Memory
    stays bounded: each frame gives at most :data:`MAX_POINTS_PER_FRAME` points and voxels are merged as
    frames arrive. ``progress(done, total)`` is called after each frame.
    """
    if not (voxel_m > 0 and max_depth_m > 0):
        raise InputError(f"voxel size ({voxel_m}) and maximum depth ({max_depth_m}) must be positive metres")
    n = len(seq.frames)
    step = max(1, math.ceil(math.sqrt(seq.camera.width * seq.camera.height / MAX_POINTS_PER_FRAME)))
    state, pending, errors, raw = None, [], [], 0
    for k in range(n):
        rows = _frame_rows(seq, k, step, voxel_m, max_depth_m)
        if isinstance(rows, str):
            errors.append(rows)
        else:
            pending.append(rows)
            raw += len(rows[0])
        # Merging into the voxels every few million points keeps memory flat for long sequences.
        if pending and (sum(len(r[0]) for r in pending) >= 2_000_000 or k == n - 1):
            parts = pending if state is None else [state, *pending]
            state, pending = _reduce(*(np.concatenate(col) for col in zip(*parts, strict=True))), []
        if progress is not None:
            progress(k + 1, n)
    if len(errors) == n:
        raise InputError(f"none of the {n} depth frames could be read (first: {errors[0]})")
    failed = len(errors)
    warnings = [*seq.warnings, *([f"skipped {failed} of {n} frames with unreadable depth"] if failed else [])]
    if state is None or len(state[0]) == 0:
        raise InputError(f"{seq.root}: no valid depth within {max_depth_m} m in any frame")
    _, sums, counts, csums, ccounts, _, frames = state
    colors = None
    if ccounts.any():  # voxels that no coloured frame saw are grey
        mean = np.divide(csums, ccounts[:, None], out=np.full_like(csums, 128.0), where=ccounts[:, None] > 0)
        colors = np.clip(np.round(mean), 0, 255).astype(np.uint8)
    centres = np.array([f.world_from_camera[:3, 3] for f in seq.frames], dtype=np.float64)
    meta = {"path": str(seq.root), "format": seq.layout, "layout": seq.layout, "unit": "m"}
    meta.update(frames=n - failed, frames_total=n, raw_points=int(raw), voxel_m=float(voxel_m))
    meta.update(max_depth_m=float(max_depth_m), pixel_step=step, depth_scale=seq.depth_scale)
    meta.update(camera=seq.camera.to_dict())
    names = [f.name for f in seq.frames]
    cloud = PointCloud(sums / counts[:, None], colors, None, centres[frames], frames, names, meta, warnings)
    return check_cloud(cloud, "m") if unit_check else cloud

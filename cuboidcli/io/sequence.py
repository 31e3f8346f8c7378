"""Posed RGB-D sequence folders (TUM, ScanNet export, Redwood, plain) and their fusion into one cloud.

Poses are camera-to-world 4x4 transforms with OpenCV camera axes (x right, y down, z forward), metres.
Every problem raises :class:`InputError` with a one-line message.
"""

from __future__ import annotations

import json
import math
import os
import re
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cuboidcli.camera import PRESETS, Camera
from cuboidcli.io import depth as depth_io
from cuboidcli.io.depth import InputError, parse_intrinsics

LAYOUTS = ("tum", "scannet", "redwood", "plain")
LAYOUT_NEEDS = (
    "TUM (rgb.txt, depth.txt, groundtruth.txt), ScanNet (depth/, pose/, intrinsic/intrinsic_depth.txt), "
    "Redwood (depth/, color/, a *.log trajectory, a camera .json) or plain (depth/, pose/, cameras.json)"
)
#: Largest time difference (s) between a TUM depth frame and its pose or RGB image.
TUM_MAX_DT = 0.02
#: Tolerance of a rotation's orthonormality, |R^T R - I|.
RIGID_TOL = 1e-3


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
    _note_colourless(frames, notes, f"an rgb.txt entry within {TUM_MAX_DT} s")
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
    stems = {p.stem for p in depth}
    if extra := sorted(p.name for p in (root / "pose").glob("*.txt") if p.stem not in stems):
        notes.append(f"{len(extra)} pose files have no depth frame (first: pose/{extra[0]}); ignored")
    _note_colourless(frames, notes, "color/<name>.jpg or .png")
    return frames


def _note_colourless(frames: list[SequenceFrame], notes: list[str], where: str) -> None:
    """A note when some frames have a colour image and others not (all or none is a layout's choice)."""
    bare = [f for f in frames if f.rgb_path is None]
    if bare and len(bare) < len(frames):
        first = bare[0].depth_path.name
        notes.append(
            f"{len(bare)} of {len(frames)} depth frames have no colour image (first: {first}, expected "
            f"{where}); their points are fused without colour and no overlay is drawn on them"
        )


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
    _note_colourless(frames, notes, "color/<name>.jpg or .png")
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

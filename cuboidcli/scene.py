"""Whole rooms: reading a scan or a posed RGB-D sequence, fitting it with the room-scale estimator
(:func:`cuboidcli.fitting.scene.fit_scene`) and packaging one "cuboids/1" result in the input's world
frame, with the outputs made from it (GLB levelled, PLY coloured by cuboid, overlays of chosen frames).
"""

from __future__ import annotations

import time
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.scene import SceneConfig, SceneInfo
from cuboidcli.io.depth import InputError
from cuboidcli.io.result import FitResult
from cuboidcli.io.scan import PointCloud, is_scan_file, read_scan
from cuboidcli.io.sequence import Sequence, fuse_sequence, read_sequence, sequence_layout

#: Up directions by name for ``--up``.
UP_NAMES = {"z": (0.0, 0.0, 1.0), "y": (0.0, 1.0, 0.0), "-y": (0.0, -1.0, 0.0), "x": (1.0, 0.0, 0.0)}
#: A cuboid is seen by a frame when at least this many of its inliers were observed from that frame.
SEEN_MIN_POINTS = 10


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


def is_scene_input(path: str | Path) -> bool:
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
class SceneInput:
    """A room ready to fit: its points in their own world frame and what is known about how they were
    seen."""

    cloud: PointCloud
    sequence: Sequence | None
    up_hint: np.ndarray
    """(3,) the direction the input calls up: the cameras' mean up, y for glTF, else z."""
    load_seconds: float


def load_scene(
    path: str | Path,
    *,
    unit: str = "m",
    every: int = 1,
    intrinsics: str | None = None,
    depth_scale: float | None = None,
    fuse_voxel_m: float = 0.02,
    progress=None,
) -> SceneInput:
    """Read a scan file or fuse a sequence folder. Raises InputError (one line) for unusable input."""
    p = Path(path)
    if not p.exists():
        raise InputError(f"not found: {p}")
    if every < 1:
        raise InputError(f"--every must be at least 1 (got {every})")
    t = time.perf_counter()
    if p.is_dir():
        seq = read_sequence(p, every=every, intrinsics=intrinsics, depth_scale=depth_scale)
        cloud = fuse_sequence(seq, voxel_m=fuse_voxel_m, progress=progress)
        cloud.warnings = [*seq.warnings, *cloud.warnings]
        ups = np.stack([f.world_from_camera[:3, :3] @ np.array([0.0, -1.0, 0.0]) for f in seq.frames])
        hint = ups.mean(0)
        if np.linalg.norm(hint) < 1e-6:
            hint = np.array([0.0, 0.0, 1.0])
        return SceneInput(cloud, seq, hint / np.linalg.norm(hint), time.perf_counter() - t)
    cloud = read_scan(p, unit=unit)
    hint = np.array([0.0, 1.0, 0.0]) if p.suffix.lower() in (".glb", ".gltf") else np.array([0.0, 0.0, 1.0])
    return SceneInput(cloud, None, hint, time.perf_counter() - t)


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


def scene_result(
    scene_input: SceneInput,
    cuboids: list[Cuboid],
    info: SceneInfo,
    config: FitConfig,
    scene: SceneConfig,
    solver_name: str,
    sampler_name: str,
    path: str | Path,
    extra_settings: dict | None = None,
) -> FitResult:
    """The "cuboids/1" result of a room, in the input's frame (``"frame": "world"``)."""
    cloud, seq = scene_input.cloud, scene_input.sequence
    fit = info.fit
    settings = {
        **replace(config, max_cuboids=scene.max_cuboids).to_dict(),
        "scene": scene.to_dict(),
        "theta_used": fit.theta,
        "solver_name": solver_name,
        "sampler_name": sampler_name,
        **(extra_settings or {}),
    }
    frames = seen_by(cloud, info.point_labels, len(cuboids))
    out = []
    for c, names in zip(cuboids, frames, strict=True):
        extras = dict(c.extras)
        if seq is not None:
            extras["frames"] = names
        out.append(Cuboid(c.center, c.half_size, c.rotation, c.inlier_gain, extras, c.kind))
    w = world_from_input(info.up.up, info.up.axes)
    inputs = {
        "path": str(path),
        **{k: v for k, v in cloud.meta.items() if k != "path"},
        "n_points": int(len(cloud.points)),
        "load_s": round(scene_input.load_seconds, 6),
        "warnings": list(cloud.warnings),
    }
    extras = {
        "fit_info": {
            "n_points": fit.n_points,
            "voxel_m": round(info.voxel_m, 6),
            "visibility": info.visibility,
            "iterations": fit.iterations,
            "batches": fit.batches,
            "stop_reason": fit.stop_reason,
            "rejected_gain": fit.rejected_gain,
            "gains": fit.gains,
            "align": fit.align,
            "aligned": fit.aligned,
            "warnings": fit.warnings,
        },
        "up": info.up.to_dict(),
        "gravity": {"down": [round(-float(v), 6) for v in info.up.up], "source": info.up.source},
        "world_from_input": w.tolist(),
        "objects": [o.to_dict(i) for i, o in enumerate(info.objects)],
    }
    if seq is not None:
        extras["frames"] = [
            {"name": f.name, "world_from_camera": f.world_from_camera.tolist()} for f in seq.frames
        ]
    camera = seq.camera if seq is not None else None
    return FitResult(camera, out, settings, info.timing_s, inputs, extras, frame="world")


def object_boxes(info: SceneInfo) -> list[Cuboid]:
    """The room's whole objects as boxes (kind ``object``), largest first; ``extras["cuboids"]`` holds the
    indices of the cuboids each is made of."""
    return [
        Cuboid(o.box.center, o.box.half_size, o.box.rotation, extras={"cuboids": list(o.cuboids)})
        for o in info.objects
    ]


def camera_cuboids(cuboids: list[Cuboid], world_from_camera: np.ndarray) -> list[Cuboid]:
    """World cuboids seen from a camera at ``world_from_camera`` (4, 4): the same boxes in its OpenCV
    coordinates."""
    inv = np.linalg.inv(world_from_camera)
    rot, t = inv[:3, :3], inv[:3, 3]
    return [
        Cuboid(rot @ c.center + t, c.half_size, rot @ c.rotation, c.inlier_gain, dict(c.extras), c.kind)
        for c in cuboids
    ]


def overlay_frames(seq: Sequence, count: int = 3) -> list[int]:
    """Indices of the frames whose overlays are drawn: the first, the last and evenly between."""
    n = len(seq.frames)
    return sorted({int(round(i)) for i in np.linspace(0, n - 1, min(count, n))})


def write_scene_outputs(
    result: FitResult,
    scene_input: SceneInput,
    info: SceneInfo,
    out_json: Path,
    *,
    glb: bool = False,
    ply: bool = False,
    overlay: bool = False,
    with_points: bool = False,
    scenes: tuple[str, ...] = (),
) -> list[Path]:
    """Write the outputs asked for and then the JSON beside them; returns the paths written. The GLB is
    levelled (+Y up), its optional points are the input's coloured by cuboid; the PLY has the input's points
    coloured by cuboid (grey: none) and the cuboid meshes; overlays are drawn on the first, middle and
    last frame of a sequence with the world cuboids projected into them."""
    from cuboidcli.export import write_scene
    from cuboidcli.export.files import output_paths
    from cuboidcli.export.glb import write_glb
    from cuboidcli.export.ply import label_colors, write_cuboid_ply, write_point_ply
    from cuboidcli.io.result import write_result

    stem = out_json.with_suffix("")
    paths = output_paths(stem, glb=glb, ply=ply, scenes=scenes)
    written = []
    cloud = scene_input.cloud
    colors = label_colors(info.point_labels)
    if glb:
        pts, pc = (cloud.points, colors) if with_points else (None, None)
        meta = {"schema": "cuboids/1", "frame": "world", "n_cuboids": len(result.cuboids)}
        glb_file = write_glb(
            paths["glb"], result.cuboids, points=pts, point_colors=pc, metadata=meta, up=info.up.up,
            objects=object_boxes(info),
        )  # fmt: skip
        written.append(glb_file)
    if ply:
        written.append(write_point_ply(paths["points_ply"], cloud.points, colors))
        written.append(write_cuboid_ply(paths["cuboids_ply"], result.cuboids))
    if overlay and scene_input.sequence is not None:
        written.extend(_write_overlays(result, scene_input.sequence, stem))
    for kind in scenes:
        if kind == "html":  # the room's own points in the viewer
            from cuboidcli.export.html import write_html

            written.append(write_html(result, paths[kind], points=cloud.points, point_colors=colors))
        else:
            written.append(write_scene(kind, result, paths[kind]))
    # the JSON last: its presence means every output of the room was written
    written.append(write_result(out_json, result))
    return written


def _write_overlays(result: FitResult, seq: Sequence, stem: Path) -> list[Path]:
    from cuboidcli.export.files import frame_overlay_path
    from cuboidcli.export.overlay import render_images, write_png
    from cuboidcli.io.depth import read_depth, read_rgb

    written = []
    for i in overlay_frames(seq):
        f = seq.frames[i]
        try:
            depth = read_depth(f.depth_path, seq.depth_scale)
            rgb = read_rgb(f.rgb_path) if f.rgb_path is not None else None
        except InputError:
            continue
        if rgb is not None and rgb.shape[:2] != depth.shape:
            import cv2

            rgb = cv2.resize(rgb, (depth.shape[1], depth.shape[0]), interpolation=cv2.INTER_AREA)
        boxes = camera_cuboids(result.cuboids, f.world_from_camera)
        images = render_images(seq.camera, boxes, rgb=rgb, depth_m=depth)
        path = frame_overlay_path(stem, f.name)
        written.append(write_png(path, images["overlay"]))
    return written


@dataclass(repr=False)
class SceneResult:
    """One fitted room: the "cuboids/1" record (``frame`` "world"), what happened while fitting
    (:class:`~cuboidcli.fitting.scene.SceneInfo`) and the input it was fitted on."""

    record: FitResult
    info: SceneInfo
    input: SceneInput

    @property
    def cuboids(self) -> list[Cuboid]:
        """The cuboids in selection order, in the input's frame, metres (each with its ``kind``)."""
        return self.record.cuboids

    @property
    def objects(self) -> list[Cuboid]:
        """One upright box per object of the room (a table with its legs, a chair with its back), largest
        first; ``extras["cuboids"]`` holds the indices of the cuboids that make it up."""
        return object_boxes(self.info)

    def save(self, path: str | Path, **outputs) -> list[Path]:
        """Write the JSON to ``path`` and the outputs asked for beside it (``glb``, ``ply``, ``overlay``,
        ``with_points``, ``scenes``); see :func:`write_scene_outputs`."""
        return write_scene_outputs(self.record, self.input, self.info, Path(path), **outputs)

    def __repr__(self) -> str:
        kinds = [c.kind for c in self.cuboids]
        return (
            f"SceneResult({len(kinds)} cuboids: {', '.join(sorted(set(kinds)))}; {len(self.info.objects)} "
            f"objects; {self.info.fit.stop_reason})"
        )

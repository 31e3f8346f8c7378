"""Fusing a posed RGB-D sequence into one point cloud in its world frame: every frame's depth
back-projected with its pose and averaged per voxel, each point keeping the camera that saw it (the
room's visibility counts against that camera)."""

from __future__ import annotations

import math
from collections.abc import Callable

import numpy as np

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.io import depth as depth_io
from cuboidcli.io.depth import InputError
from cuboidcli.io.scan import PointCloud
from cuboidcli.io.sequence import Sequence, SequenceFrame
from cuboidcli.load.units import check_cloud

#: Pixels back-projected per frame at most: larger frames take every k-th pixel.
MAX_POINTS_PER_FRAME = 80_000
#: Voxel indices run over [-_HALF, _HALF) per axis, 21 bits each in one int64 key.
_HALF = 1 << 20


def _reduce(keys, sums, counts, csums, ccounts, dists, frames):
    """Merge rows that share a voxel key: sums add up, the observation nearest to the voxel centre stays
    (on a tie the earlier row, i.e. the earlier frame: a stable sort keeps the result deterministic)."""
    if len(keys) == 0:  # no frame so far had valid depth: nothing to merge (reduceat needs a row)
        return keys, sums, counts, csums, ccounts, dists, frames
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

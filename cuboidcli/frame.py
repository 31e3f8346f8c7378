"""Loading one frame's inputs (depth, or RGB with depth estimated from it, and intrinsics) as a
:class:`FrameInput` that :meth:`cuboidcli.api.Fitter.fit_frame` fits: what ``cuboids fit`` reads for one
frame and for each frame of a folder (:class:`cuboidcli.folder.FrameJob`)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cuboidcli.camera import PRESETS, Camera
from cuboidcli.factories import DepthModelOptions, depth_estimator
from cuboidcli.io.depth import (
    InputError,
    check_inputs,
    intrinsics_for_size,
    parse_intrinsics,
    read_depth,
    read_rgb,
)
from cuboidcli.io.photo import DEFAULT_FOV_DEG, centred_intrinsics, default_camera, read_photo
from cuboidcli.io.result import input_record


@dataclass
class FrameInput:
    depth_m: np.ndarray
    camera: Camera
    rgb: np.ndarray | None
    depth_scale: float
    notes: list[str]
    meta: dict
    depth_seconds: float | None = None
    """Seconds the depth estimation from RGB took (None: the depth was given)."""


def resolve_depth_scale(depth_scale: float | None, intr: Camera, preset: str | None) -> float:
    """Explicit option > intrinsics file > preset > millimetres."""
    if depth_scale is not None:
        if depth_scale <= 0:
            raise InputError(f"--depth-scale must be positive (got {depth_scale})")
        return depth_scale
    if intr.depth_scale is not None:
        return intr.depth_scale
    if preset is not None:
        return float(PRESETS[preset]["depth_scale"])
    return 0.001


def load_frame(
    depth_path: str | Path | None,
    image_path: str | Path | None = None,
    intrinsics: str | None = None,
    preset: str | None = None,
    depth_scale: float | None = None,
    frame_name: str | None = None,
    depth_model: DepthModelOptions | None = None,
) -> FrameInput:
    """Read and check one frame. Raises InputError with a one-line message on unusable input.

    Without ``depth_path`` the depth is estimated from the RGB image (``depth_model`` options). The
    intrinsics come, in this order, from ``intrinsics`` (``-K``) or ``preset`` (scaled to the image when
    its aspect ratio matches), from the photo's EXIF, from the depth model when it predicts the focal
    length, else from a default field of view (with a warning); ``meta["intrinsics_source"]`` says which.
    A photo's EXIF orientation is applied, so the frame is upright; ``-K`` describes the upright image.
    """
    if preset is not None and preset not in PRESETS:
        raise InputError(f"unknown --camera {preset!r}; choose one of: {', '.join(PRESETS)}")
    if depth_path is None and image_path is None:
        raise InputError("give a depth map (--depth D.png) or an RGB image")
    name = frame_name or Path(depth_path if depth_path is not None else image_path).stem
    given = parse_intrinsics(intrinsics, preset, frame=name) if intrinsics or preset else None
    scale = resolve_depth_scale(depth_scale, given or _NO_INTRINSICS, preset)
    depth = read_depth(depth_path, scale) if depth_path is not None else None
    notes: list[str] = []
    rgb, exif = None, None
    if image_path is not None:
        photo = read_photo(image_path)
        notes += photo.notes
        rgb, exif = _registered(photo, image_path, depth)
    h, w = depth.shape if depth is not None else rgb.shape[:2]
    intr = intrinsics_for_size(given, w, h, None if intrinsics else preset) if given else exif
    source = None
    timing: dict = {}
    if depth is None:
        opts = depth_model or DepthModelOptions()
        depth, source, intr = _estimate_depth(rgb, intr, scale, opts, timing, notes)
    elif intr is None:
        intr = default_camera(w, h)
        notes.append(_guessed(intr))
    notes += check_inputs(depth, intr, None if rgb is None else rgb.shape)
    camera = intr.with_size(w, h)
    meta = input_record(
        depth,
        depth=depth_path,
        image=image_path,
        depth_source=source or "depth map",
        depth_scale=scale,
        intrinsics_source=intr.source,
    )
    if "edges_dropped" in timing:
        meta["depth_edges_dropped"] = round(float(timing["edges_dropped"]), 6)
    return FrameInput(depth, camera, rgb, scale, notes, meta, timing.get("depth"))


#: Stands in for "no intrinsics given" where only their depth scale is asked for.
_NO_INTRINSICS = Camera(0.0, 0.0, 0.0, 0.0)


def _guessed(intr: Camera) -> str:
    return (
        f"no camera intrinsics (no -K, --camera or EXIF focal length): assuming a {DEFAULT_FOV_DEG:g} degree "
        f"field of view across the long side (fx = {intr.fx:.1f} px); pass -K fx,fy,cx,cy for exact boxes"
    )


def _registered(photo, image_path, depth: np.ndarray | None) -> tuple[np.ndarray, Camera | None]:
    """The photo's pixels and EXIF intrinsics as the frame uses them: upright; beside a depth map, the
    orientation whose size matches the depth map (a depth map is registered to the stored pixels when the
    camera wrote its orientation only as a tag)."""
    rgb, exif = photo.rgb, photo.exif_camera
    if depth is None or rgb.shape[:2] == depth.shape or photo.orientation == 1:
        return rgb, exif
    stored = read_rgb(image_path)
    if stored.shape[:2] == depth.shape:
        return stored, None  # EXIF intrinsics are for the upright image; the depth map is not upright
    return rgb, exif


def _estimate_depth(
    rgb: np.ndarray,
    intr: Camera | None,
    depth_scale: float,
    opts: DepthModelOptions,
    timing: dict,
    notes: list[str],
) -> tuple[np.ndarray, str, Camera]:
    """Depth from the image: (depth_m, description, the intrinsics used). Without intrinsics a model that
    predicts the focal length supplies them; otherwise the default field of view is assumed."""
    from cuboidcli.depth import estimate_depth

    h, w = rgb.shape[:2]
    try:
        estimator = depth_estimator(opts, depth_scale)
        if intr is None and getattr(estimator, "predicts_focal", False):
            t0 = time.perf_counter()
            depth, focal = estimator.predict_with_focal(rgb)
            timing["depth"] = time.perf_counter() - t0
            if not (depth > 0).any():
                raise ValueError(f"{estimator.describe()}: the estimated depth has no positive values")
            intr = centred_intrinsics(focal, w, h, f"depth model: {estimator.describe()}")
            source = estimator.describe()
            return _edges_dropped(depth, intr, opts, source, timing), source, intr
        if intr is None:
            intr = default_camera(w, h)
            notes.append(_guessed(intr))
        depth, source = estimate_depth(estimator, rgb, intr.with_size(w, h), timing)
        return _edges_dropped(depth, intr, opts, source, timing), source, intr
    except (ValueError, FileNotFoundError, ImportError) as e:
        raise InputError(str(e)) from e


def _edges_dropped(depth: np.ndarray, intr: Camera, opts: DepthModelOptions, source: str, timing: dict):
    """The estimate without its pixels on depth discontinuities when ``opts.drop_edges`` asks for it (the
    time counts as part of the depth stage); ``timing["edges_dropped"]`` gets the share of pixels left out."""
    if not opts.drop_edges:
        return depth
    from cuboidcli.depth.edges import drop_depth_edges

    t0 = time.perf_counter()
    depth, dropped = drop_depth_edges(depth, focal_px=math.sqrt(intr.fx * intr.fy))
    timing["depth"] = timing.get("depth", 0.0) + time.perf_counter() - t0
    timing["edges_dropped"] = dropped
    if not (depth > 0).any():
        raise ValueError(f"{source}: no depth is left after dropping its edges (try --keep-depth-edges)")
    return depth

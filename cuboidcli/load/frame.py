"""Loading a frame: a depth map (a file or an array) with its camera, or a photo whose depth a network
estimates (:func:`depth_from_rgb`, the one place depth comes from RGB). The camera is resolved by
:mod:`cuboidcli.load.camera`. A photo's EXIF orientation is applied, so the frame is upright; ``-K``
describes the upright image. A frame's photo (alone or beside its depth map) is read for its lines once,
here (:func:`photo_lines`): its camera where nothing surer gives one, and the fit's prior on the down
direction and the room's axes (``FrameData.lines``, recorded as the result's ``input.lines``)."""

from __future__ import annotations

import math
import time
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.factories import DepthModelOptions, depth_estimator
from cuboidcli.geometry.vanishing import LineEstimate, estimate_from_lines
from cuboidcli.io.depth import InputError, check_inputs, read_depth, read_rgb
from cuboidcli.io.photo import read_photo
from cuboidcli.io.result import input_record
from cuboidcli.load import camera as cameras


@dataclass
class DepthEstimate:
    """Depth predicted from an RGB image, with the camera it was predicted for."""

    depth_m: np.ndarray
    """(H, W) float32 metres, 0 = no estimate."""
    source: str
    """The model, in one line (the result's ``input.depth_source``)."""
    camera: Camera
    """The camera used: the one given, else the model's focal length or the default field of view."""
    seconds: float
    """The estimation itself (loading the model is start-up and not counted)."""
    edges_dropped: float | None = None
    """The share of pixels left out on depth discontinuities, when asked for."""
    notes: list[str] = field(default_factory=list)


def depth_from_rgb(
    rgb: np.ndarray,
    camera: Camera | None,
    opts: DepthModelOptions | None = None,
    depth_scale: float = 0.001,
    lines: LineEstimate | None = None,
) -> DepthEstimate:
    """Metric depth of an RGB image (H, W, 3) uint8 by the depth model of ``opts`` (None: the built-in
    network), loaded once per process. ``camera`` None: a model that predicts the focal length supplies it,
    else the default field of view is assumed (a note says so), unless the photo's ``lines`` rule it out
    (:func:`cuboidcli.load.camera.default_for`). ``depth_scale`` is that of a ``--partial-depth`` PNG.
    Raises InputError for an unusable model or estimate."""
    from cuboidcli.depth import estimate_depth

    opts = opts or DepthModelOptions()
    h, w = rgb.shape[:2]
    notes: list[str] = []
    timing: dict = {}
    try:
        estimator = depth_estimator(opts, depth_scale)
        if camera is None and getattr(estimator, "predicts_focal", False):
            t0 = time.perf_counter()
            depth, focal = estimator.predict_with_focal(rgb)
            timing["depth"] = time.perf_counter() - t0
            if not (depth > 0).any():
                raise ValueError(f"{estimator.describe()}: the estimated depth has no positive values")
            source = estimator.describe()
            camera = cameras.from_focal(focal, w, h, f"depth model: {source}")
        else:
            if camera is None:
                camera = cameras.default_for(w, h, notes, lines)
            depth, source = estimate_depth(estimator, rgb, camera.with_size(w, h), timing)
        dropped = None
        if opts.drop_edges:
            from cuboidcli.depth.edges import drop_depth_edges

            t0 = time.perf_counter()
            depth, dropped = drop_depth_edges(depth, focal_px=math.sqrt(camera.fx * camera.fy))
            timing["depth"] = timing.get("depth", 0.0) + time.perf_counter() - t0
            if not (depth > 0).any():
                raise ValueError(
                    f"{source}: no depth is left after dropping its edges (try --keep-depth-edges)"
                )
    except (ValueError, FileNotFoundError, ImportError) as e:
        raise InputError(str(e)) from e
    return DepthEstimate(depth, source, camera, timing.get("depth", 0.0), dropped, notes)


@dataclass
class FrameData:
    """A frame ready to fit: its depth map, camera and image, with the ``input`` record of the result."""

    depth_m: np.ndarray
    camera: Camera
    rgb: np.ndarray | None
    notes: list[str]
    meta: dict
    depth_seconds: float | None = None
    """Seconds the depth estimation from RGB took (None: the depth was given)."""
    lines: LineEstimate | None = None
    """What the photo's lines say (down, focal length, room axes) in ``camera``'s frame; None without a
    photo or without lines in it."""
    lines_seconds: float | None = None
    """Seconds finding the lines took (None: no photo to look at)."""


def photo_lines(rgb: np.ndarray, camera: Camera | None) -> tuple[LineEstimate | None, float]:
    """The lines' estimate of an upright photo (H, W, 3) uint8 seen by ``camera`` (None: the focal length
    is estimated too, the principal point at the centre), and the seconds it took."""
    t0 = time.perf_counter()
    if camera is None:
        est = estimate_from_lines(rgb)
    else:
        est = estimate_from_lines(rgb, camera.fx, camera.fy, camera.cx, camera.cy)
    return est, time.perf_counter() - t0


def lines_in(lines: LineEstimate | None, camera: Camera) -> LineEstimate | None:
    """The lines' estimate in the frame of the camera the frame is fitted with (the vanishing points
    back-projected by it; see :meth:`LineEstimate.seen_by`)."""
    return None if lines is None else lines.seen_by(camera.fx, camera.fy, camera.cx, camera.cy)


def load_frame(
    depth_path: str | Path | None,
    image_path: str | Path | None = None,
    intrinsics: str | None = None,
    preset: str | None = None,
    depth_scale: float | None = None,
    frame_name: str | None = None,
    depth_model: DepthModelOptions | None = None,
) -> FrameData:
    """Read and check one frame: a depth map (``depth_path``, with its photo ``image_path`` if any), or a
    photo alone whose depth is estimated (``depth_model``). Raises InputError with a one-line message on
    unusable input."""
    cameras.check_preset(preset)
    if depth_path is None and image_path is None:
        raise InputError("give a depth map (--depth D.png) or an RGB image")
    name = frame_name or Path(depth_path if depth_path is not None else image_path).stem
    given = cameras.given_camera(intrinsics, preset, frame=name)
    scale = cameras.resolve_depth_scale(depth_scale, given, preset)
    depth = read_depth(depth_path, scale) if depth_path is not None else None
    notes: list[str] = []
    rgb, exif = None, None
    if image_path is not None:
        photo = read_photo(image_path)
        notes += photo.notes
        rgb, exif = _registered(photo, image_path, depth)
    h, w = depth.shape if depth is not None else rgb.shape[:2]
    camera = cameras.sized(given, w, h, intrinsics, preset) if given else exif
    lines, lines_seconds = None, None
    if rgb is not None and rgb.shape[:2] == (h, w):  # an unregistered photo is refused below
        lines, lines_seconds = photo_lines(rgb, camera)
        camera = camera or cameras.from_lines(lines, w, h)
    source, seconds, extra = "depth map", None, {}
    if depth is None:
        est = depth_from_rgb(rgb, camera, depth_model, scale, lines)
        depth, source, camera, seconds = est.depth_m, est.source, est.camera, est.seconds
        notes += est.notes
        if est.edges_dropped is not None:
            extra["depth_edges_dropped"] = round(float(est.edges_dropped), 6)
    elif camera is None:
        camera = cameras.default_for(w, h, notes, lines)
    notes += check_inputs(depth, camera, None if rgb is None else rgb.shape)
    meta = input_record(
        depth,
        depth=depth_path,
        image=image_path,
        depth_source=source,
        depth_scale=scale,
        intrinsics_source=camera.source,
    )
    camera = camera.with_size(w, h)
    lines = lines_in(lines, camera)
    if lines is not None:
        extra["lines"] = lines.to_dict()
    return FrameData(depth, camera, rgb, notes, {**meta, **extra}, seconds, lines, lines_seconds)


def array_frame(depth_m, camera: Camera, rgb: np.ndarray | None = None) -> FrameData:
    """A depth map given as an array (H, W) metres (0, NaN, inf = missing) seen by ``camera`` (a width
    and height of 0 take the array's). Raises ValueError for unusable input."""
    depth_m = np.asarray(depth_m)
    if depth_m.ndim != 2 or not np.issubdtype(depth_m.dtype, np.number):
        raise ValueError(f"depth_m must be a 2-D array of metres, got {depth_m.shape} {depth_m.dtype}")
    depth_m = np.where(valid_depth(depth_m), depth_m, 0.0).astype(np.float32)
    h, w = depth_m.shape
    camera = camera.for_image(w, h)
    notes = check_inputs(depth_m, camera, None if rgb is None else np.shape(rgb))
    meta = input_record(
        depth_m, depth=None, image=None, depth_source="array", depth_scale=None, intrinsics_source="api"
    )
    return FrameData(depth_m, camera, rgb, notes, meta)


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

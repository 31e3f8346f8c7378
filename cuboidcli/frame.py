"""Loading one frame's inputs (depth, or RGB with depth estimated from it, and intrinsics) and packaging a
fit as a FitResult: what ``cuboids fit`` and a folder of frames run around :class:`cuboidcli.api.Fitter`."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cuboidcli.camera import PRESETS, Camera, valid_depth
from cuboidcli.cuboid import Cuboid
from cuboidcli.factories import DepthModelOptions, depth_estimator
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import FitInfo
from cuboidcli.io.depth import InputError, Intrinsics, check_inputs, parse_intrinsics, read_depth, read_rgb
from cuboidcli.io.result import FitResult


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


def resolve_depth_scale(depth_scale: float | None, intr: Intrinsics, preset: str | None) -> float:
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

    Without ``depth_path`` the depth is estimated from the RGB image (``depth_model`` options).
    """
    if preset is not None and preset not in PRESETS:
        raise InputError(f"unknown --preset {preset!r}; choose one of: {', '.join(PRESETS)}")
    if depth_path is None and image_path is None:
        raise InputError("give a depth map (--depth D.png) or an RGB image")
    notes: list[str] = []
    if intrinsics is None and preset is None:
        notes.append("no --intrinsics or --preset given: using the NYU Depth v2 intrinsics")
    name = frame_name or Path(depth_path if depth_path is not None else image_path).stem
    intr = parse_intrinsics(intrinsics, preset, frame=name)
    scale = resolve_depth_scale(depth_scale, intr, preset)
    rgb = read_rgb(image_path) if image_path is not None else None
    source = None
    timing: dict = {}
    if depth_path is not None:
        depth = read_depth(depth_path, scale)
    else:
        depth, source = _estimate_depth(rgb, intr, scale, depth_model or DepthModelOptions(), timing)
    notes += check_inputs(depth, intr, None if rgb is None else rgb.shape)
    h, w = depth.shape
    camera = intr.camera(w, h)
    meta = {
        "depth": None if depth_path is None else str(depth_path),
        "image": None if image_path is None else str(image_path),
        "depth_source": source or "depth map",
        "depth_scale": scale,
        "width": w,
        "height": h,
        "valid_fraction": round(float(valid_depth(depth).mean()), 6),
        "intrinsics_source": intr.source,
    }
    return FrameInput(depth, camera, rgb, scale, notes, meta, timing.get("depth"))


def _estimate_depth(
    rgb: np.ndarray, intr: Intrinsics, depth_scale: float, opts: DepthModelOptions, timing: dict
):
    from cuboidcli.depth import estimate_depth

    h, w = rgb.shape[:2]
    try:
        estimator = depth_estimator(opts, depth_scale)
        return estimate_depth(estimator, rgb, intr.camera(w, h), timing)
    except (ValueError, FileNotFoundError) as e:
        raise InputError(str(e)) from e


def make_result(
    camera: Camera,
    cuboids: list[Cuboid],
    info: FitInfo,
    config: FitConfig,
    input_meta: dict,
    solver_name: str,
    sampler_name: str,
    extra_settings: dict | None = None,
) -> FitResult:
    settings = {
        **config.to_dict(),
        "theta_used": info.theta,
        "solver_name": solver_name,
        "sampler_name": sampler_name,
        **(extra_settings or {}),
    }
    fit_info = {
        "n_points": info.n_points,
        "grid_step": info.grid_step,
        "iterations": info.iterations,
        "batches": info.batches,
        "stop_reason": info.stop_reason,
        "rejected_gain": info.rejected_gain,
        "gains": info.gains,
        "align": info.align,
        "aligned": info.aligned,
        "warnings": info.warnings,
    }
    extras = {"fit_info": fit_info}
    if info.gravity is not None:
        extras["gravity"] = info.gravity.to_dict()
        extras["world_from_camera"] = info.gravity.world_from_camera().tolist()
    return FitResult(
        camera=camera,
        cuboids=cuboids,
        settings=settings,
        timing_s=info.timing_s,
        input=input_meta,
        extras=extras,
    )


def same_settings(saved: dict, config: FitConfig, extra_settings: dict | None = None) -> bool:
    """Whether a saved result's ``settings`` (as :func:`make_result` writes them) are those of ``config``
    and ``extra_settings`` (the weights used): a rerun may then keep that result instead of fitting again."""
    import json

    wanted = {**json.loads(json.dumps(config.to_dict())), **(extra_settings or {})}
    return all(saved.get(k) == v for k, v in wanted.items())

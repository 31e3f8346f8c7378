"""Loading one frame's inputs (depth, optional RGB, intrinsics) and packaging a fit as a FitResult."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cuboidcli.camera import PRESETS, Camera, valid_depth
from cuboidcli.cuboid import Cuboid
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
    depth_path: str | Path,
    image_path: str | Path | None = None,
    intrinsics: str | None = None,
    preset: str | None = None,
    depth_scale: float | None = None,
    frame_name: str | None = None,
) -> FrameInput:
    """Read and check one frame. Raises InputError with a one-line message on unusable input."""
    if preset is not None and preset not in PRESETS:
        raise InputError(f"unknown --preset {preset!r}; choose one of: {', '.join(PRESETS)}")
    notes: list[str] = []
    if intrinsics is None and preset is None:
        notes.append("no --intrinsics or --preset given: using the NYU Depth v2 intrinsics")
    intr = parse_intrinsics(intrinsics, preset, frame=frame_name or Path(depth_path).stem)
    scale = resolve_depth_scale(depth_scale, intr, preset)
    depth = read_depth(depth_path, scale)
    rgb = read_rgb(image_path) if image_path is not None else None
    notes += check_inputs(depth, intr, None if rgb is None else rgb.shape)
    h, w = depth.shape
    camera = intr.camera(w, h)
    meta = {
        "depth": str(depth_path),
        "image": None if image_path is None else str(image_path),
        "depth_scale": scale,
        "width": w,
        "height": h,
        "valid_fraction": round(float(valid_depth(depth).mean()), 6),
        "intrinsics_source": intr.source,
    }
    return FrameInput(depth, camera, rgb, scale, notes, meta)


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
        "iterations": info.iterations,
        "stop_reason": info.stop_reason,
        "rejected_gain": info.rejected_gain,
        "gains": info.gains,
    }
    return FitResult(
        camera=camera,
        cuboids=cuboids,
        settings=settings,
        timing_s=info.timing_s,
        input=input_meta,
        extras={"fit_info": fit_info},
    )

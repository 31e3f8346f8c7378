"""A data set's frame fitted for an evaluation, through :meth:`cuboidcli.api.Fitter.fit`, and the fits
``--save-fits`` keeps: ``<dir>/seed<seed>/<frame>.json``, "cuboids/1" files that ``cuboids export`` opens
and that a rerun scores instead of fitting again when they were made with the same settings."""

from __future__ import annotations

import warnings
from dataclasses import replace
from pathlib import Path

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.config import FitConfig
from cuboidcli.geometry.gravity import Gravity
from cuboidcli.io.depth import InputError, InputWarning
from cuboidcli.io.result import same_settings, saved_settings, write_result


def saved_fit_path(save_fits_dir: Path, seed: int, name: str) -> Path:
    """Where ``--save-fits`` keeps a frame's fit: <dir>/seed<seed>/<frame>.json."""
    return Path(save_fits_dir) / f"seed{seed}" / f"{name}.json"


def _weights_setting(weights_dir: Path | None) -> dict:
    """The weights entry of a saved fit's settings (what a rerun compares)."""
    return {"weights": None if weights_dir is None else str(weights_dir)}


def dataset_input(frame) -> dict:
    """What a saved fit records about its input: the data set's frame (its name; for the NYU file, the file
    and index) and the keys ``cuboids fit`` writes that ``cuboids export`` reads the frame back with."""
    depth_path = getattr(frame, "depth_path", None)
    rgb_path = getattr(frame, "rgb_path", None)
    meta = {
        "frame": frame.name,
        "depth": None if depth_path is None else str(depth_path),
        "image": None if rgb_path is None else str(rgb_path),
        "width": frame.camera.width,
        "height": frame.camera.height,
    }
    if hasattr(frame, "depth_scale"):
        meta["depth_scale"] = frame.depth_scale
    if hasattr(frame, "mat_path"):  # NYU labelled file
        meta.update(mat=str(frame.mat_path), index=frame.index)
    return meta


def photo_input(frame, depth_model: Path | None):
    """The frame to fit from its RGB image alone, as ``cuboids fit PHOTO -K ...`` reads a photo: an
    :class:`~cuboidcli.load.Input` of source "photo" with the depth predicted from the image (the seconds
    it took) and the image's lines in the frame's camera (the prior on the down direction and the room's
    axes, which come first for predicted depth), recorded as ``input.lines``. The estimator is built once
    per process (loading it is start-up, not fitting time)."""
    from cuboidcli.factories import DepthModelOptions
    from cuboidcli.load import Input
    from cuboidcli.load.frame import depth_from_rgb, photo_lines

    rgb = frame.rgb() if hasattr(frame, "rgb") else None
    if rgb is None:
        raise InputError(f"frame {frame.name}: --rgb needs an RGB image, and this frame has none")
    try:
        opts = DepthModelOptions(None if depth_model is None else str(depth_model))
        estimate = depth_from_rgb(rgb, frame.camera, opts)
    except ValueError as e:
        raise InputError(f"frame {frame.name}: {e}") from e
    lines, lines_s = (
        photo_lines(rgb, frame.camera) if rgb.shape[:2] == estimate.depth_m.shape else (None, None)
    )
    meta = dataset_input(frame)
    if lines is not None:
        meta["lines"] = lines.to_dict()
    return Input(
        "photo", frame.camera, meta, [], estimate.depth_m, rgb, estimate.seconds,
        lines=lines, lines_seconds=lines_s,
    )  # fmt: skip


def fit_and_save(
    frame,
    depth_m: np.ndarray,
    config: FitConfig,
    weights_dir: Path | None,
    save_fits_dir: Path | None,
    rgb: bool = False,
    depth_model: Path | None = None,
) -> tuple[list[Cuboid], dict, Gravity | None]:
    """Fit one frame with ``config`` (its seed is the run's) and, with ``save_fits_dir``, save its
    "cuboids/1" result: (cuboids, timing_s, the gravity the fit used or estimated, ``FitInfo.gravity``).

    With ``rgb`` the fit is of the depth predicted from the frame's image (``depth_m`` is unused), with
    the image's lines as the prior on the down direction (:func:`photo_input`), and ``timing_s["total"]``
    includes the depth estimation and the lines (``timing_s["depth"]``, ``timing_s["lines"]``).
    """
    from cuboidcli.job import fitter_for
    from cuboidcli.load import Input, load

    photo = photo_input(frame, depth_model) if rgb else None
    weights = None if weights_dir is None else str(weights_dir)
    try:
        # The estimator of this configuration is built once per process (any seed: it is the fit's).
        fitter = fitter_for(replace(config, seed=0), weights, None)
        with warnings.catch_warnings():
            # Every frame of the data set is scored as it is; notes on its input are no part of the report.
            warnings.simplefilter("ignore", InputWarning)
            if photo is None:
                fit = fitter.fit(depth_m, frame.camera, seed=config.seed)
            else:  # the depth array read as Fitter.fit reads it, fitted as the photo it came from
                read = load(photo.depth_m, camera=frame.camera)
                fit = fitter.fit_input(
                    replace(photo, depth_m=read.depth_m, camera=read.camera), seed=config.seed
                )
    except (ValueError, FileNotFoundError, ImportError) as e:  # bad settings, weights or input: one line
        raise InputError(f"frame {frame.name}: {e}") from e
    info = fit.info
    if save_fits_dir is not None:
        # Recorded as the evaluation asked for it: the configured names and weights, the data set's frame.
        from cuboidcli.result import result_record

        result = result_record(
            Input("depth", frame.camera, dataset_input(frame) if photo is None else photo.meta),
            fit.cuboids,
            info,
            config.for_kind("frame"),
            config.solver,
            config.sampler,
            _weights_setting(weights_dir),
        )
        write_result(saved_fit_path(save_fits_dir, config.seed, frame.name), result)
    return fit.cuboids, dict(info.timing_s), info.gravity


def reusable_fit(path: Path, config: FitConfig, weights_dir: Path | None) -> bool:
    """A saved fit that a rerun may score instead of fitting: valid "cuboids/1", the same settings."""
    saved = saved_settings(path, [path])
    return saved is not None and same_settings(saved, config.for_kind("frame"), _weights_setting(weights_dir))

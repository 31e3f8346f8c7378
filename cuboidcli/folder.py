"""Fitting every frame of a folder, resumably: what ``cuboids fit DIR`` runs on any engine of
:mod:`cuboidcli.scaleout`.

A frame's output is ``<out>/<stem>_cuboids.json`` plus the images and meshes asked for; the JSON is written
last and atomically, so its presence means the frame is complete. A rerun skips frames whose JSON is a
valid "cuboids/1" file fitted with the same settings (:func:`is_complete`).
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

from cuboidcli.fitting.config import FitConfig
from cuboidcli.scaleout import Outcome, failed


@dataclass(frozen=True)
class FolderJob:
    """Everything but the input file: how to read a frame, fit it and write its outputs. Picklable: it is
    sent to worker processes and Ray tasks, which build their :class:`~cuboidcli.api.Fitter` from it once."""

    config: FitConfig
    weights: str | None = None
    onnx: str | None = None
    intrinsics: str | None = None
    preset: str | None = None
    depth_scale: float | None = None
    depth_model: object = None
    """:class:`~cuboidcli.factories.DepthModelOptions` for RGB input (the depth comes from the image);
    None for depth maps."""
    glb: bool = False
    ply: bool = False
    overlay: bool = False
    with_points: bool = False
    scenes: tuple[str, ...] = ()
    """Scene files written beside each JSON (kinds of :data:`cuboidcli.export.SCENES`)."""

    def outputs(self, out_json: Path) -> list[Path]:
        """The files a complete frame has, the JSON last (see :meth:`cuboidcli.api.Result.save`)."""
        return output_files(out_json, glb=self.glb, ply=self.ply, overlay=self.overlay, scenes=self.scenes)


def output_files(
    out_json: Path, *, glb: bool, ply: bool, overlay: bool, scenes: tuple[str, ...]
) -> list[Path]:
    """The files beside ``out_json`` that ``cuboids fit`` writes for these outputs, the JSON last."""
    stem = out_json.with_name(out_json.name.removesuffix(".json"))
    extra = []
    if glb:
        extra.append(Path(f"{stem}.glb"))
    if ply:
        extra += [Path(f"{stem}_points.ply"), Path(f"{stem}_cuboids.ply")]
    if overlay:
        extra += [Path(f"{stem}_{k}.png") for k in ("overlay", "labels", "labels_color", "panel")]
    if scenes:
        from cuboidcli.export import scene_path

        extra += [scene_path(stem, kind) for kind in scenes]
    return [*extra, out_json]


@lru_cache(maxsize=4)
def fitter_for(config: FitConfig, weights: str | None, onnx: str | None):
    """The Fitter of a configuration, built once per process (a worker fits many frames with it)."""
    from cuboidcli.api import Fitter

    return Fitter(config, weights=weights, onnx=onnx, device=config.device)


def saved_settings(out_json: Path, outputs: list[Path]) -> dict | None:
    """The ``settings`` of a finished result: None unless every file of ``outputs`` exists and
    ``out_json`` is a valid "cuboids/1" result with settings (a rerun fits it again then)."""
    from cuboidcli.io.result import read_result

    if not all(p.is_file() for p in outputs):
        return None
    try:
        saved = read_result(out_json)
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return saved.settings if isinstance(saved.settings, dict) else None


def is_complete(out_json: Path, job: FolderJob) -> bool:
    """The frame's outputs exist and its JSON is a valid "cuboids/1" result fitted with ``job``'s settings."""
    from cuboidcli.frame import same_settings

    saved = saved_settings(out_json, job.outputs(out_json))
    extra = {"weights": job.weights, "onnx": job.onnx}
    return saved is not None and same_settings(saved, job.config, extra)


def fit_file(job: FolderJob, source: str, out_json: str) -> Outcome:
    """Fit one frame (``source``: a depth map, or an image with ``job.depth_model``) and write its outputs.
    Returns the Outcome (failed with a one-line message for unusable input); ``value`` is
    (cuboids, seconds, depth source)."""
    import warnings

    from cuboidcli.frame import load_frame

    name = Path(source).name
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            fitter = fitter_for(job.config, job.weights, job.onnx)
            depth, image = (None, source) if job.depth_model is not None else (source, None)
            frame = load_frame(
                depth, image, job.intrinsics, job.preset, job.depth_scale, depth_model=job.depth_model
            )
            result = fitter.fit_frame(frame)
            result.save(
                out_json,
                glb=job.glb,
                ply=job.ply,
                overlay=job.overlay,
                with_points=job.with_points,
                scenes=job.scenes,
            )
    except Exception as e:  # this frame fails; the run goes on
        return failed(name, e)
    notes = frame.notes + [str(w.message) for w in caught]
    value = (len(result.cuboids), result.info.timing_s["total"], frame.meta["depth_source"])
    return Outcome(name, "done", value=value, notes=notes)

"""Fitting every room of a folder (scan files, or sequence folders inside it), resumably, on any engine of
:mod:`cuboidcli.scaleout` (local processes or Ray): what ``cuboids fit DIR`` runs for a folder of rooms,
such as a data set of scans.

A room's output is ``<out>/<name>_cuboids.json`` plus the files asked for; the JSON is written last and
atomically, so its presence means the room is complete, and a rerun skips rooms whose JSON was fitted with
the same settings.
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from cuboidcli.export.files import output_files
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.scene import SceneConfig
from cuboidcli.folder import fitter_for
from cuboidcli.io.result import same_settings, saved_settings
from cuboidcli.scaleout import Outcome, failed


@dataclass(frozen=True)
class RoomJob:
    """Everything but the input path: how to read a room, fit it and write its outputs. Picklable: workers
    and Ray tasks build their Fitter from it once (:func:`cuboidcli.folder.fitter_for`)."""

    config: FitConfig
    scene: SceneConfig
    weights: str | None = None
    onnx: str | None = None
    unit: str = "m"
    every: int = 1
    intrinsics: str | None = None
    depth_scale: float | None = None
    glb: bool = False
    ply: bool = False
    with_points: bool = False
    scenes: tuple[str, ...] = ()

    def outputs(self, out_json: Path) -> list[Path]:
        """The files a complete room has, the JSON last."""
        return output_files(out_json, glb=self.glb, ply=self.ply, overlay=False, scenes=self.scenes)

    def is_complete(self, out_json: Path) -> bool:
        """The room's outputs exist and its JSON was fitted with this job's settings."""
        saved = saved_settings(out_json, self.outputs(out_json))
        if saved is None:
            return False
        config = replace(self.config, max_cuboids=self.scene.max_cuboids)
        extra = {"weights": self.weights, "onnx": self.onnx}
        return same_settings(saved.get("scene") or {}, self.scene) and same_settings(saved, config, extra)


def rooms_in(folder: Path) -> list[Path]:
    """The rooms of a folder, sorted: its scan files and its sub-folders laid out as sequences."""
    from cuboidcli.scene import is_scene_input

    return sorted(p for p in folder.iterdir() if not p.name.startswith(".") and is_scene_input(p))


def is_rooms_folder(path: Path) -> bool:
    """A folder of rooms (scan files, sequence sub-folders) and no images (which would make it a folder of
    frames)."""
    from cuboidcli.io.inputs import has_images

    return path.is_dir() and not has_images(path) and bool(rooms_in(path))


def fit_room_file(job: RoomJob, source: str, out_json: str) -> Outcome:
    """Fit one room and write its outputs; a failed Outcome (one line) for unusable input. ``value`` is
    (cuboids, fitting seconds, fitting points)."""
    import warnings

    name = Path(source).name
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            fitter = fitter_for(job.config, job.weights, job.onnx)
            res = fitter.fit_scene(
                source, scene=job.scene, unit=job.unit, every=job.every, intrinsics=job.intrinsics,
                depth_scale=job.depth_scale,
            )  # fmt: skip
            res.save(out_json, glb=job.glb, ply=job.ply, with_points=job.with_points, scenes=job.scenes)
    except Exception as e:  # this room fails; the run goes on
        return failed(name, e)
    notes = list(res.record.input.get("warnings", [])) + [str(w.message) for w in caught]
    value = (len(res.cuboids), res.record.timing_s["total"], res.info.fit.n_points)
    return Outcome(name, "done", value=value, notes=notes)

"""One job for ``cuboids fit``'s frames: :class:`FrameJob` reads, fits and writes one frame, and the same
job fits every frame of a folder, resumably, on any engine of :mod:`cuboidcli.scaleout` (:func:`fit_file`
is its task).

A frame's output is ``<out>/<stem>_cuboids.json`` plus the images and meshes asked for
(:mod:`cuboidcli.export.files`); the JSON is written last and atomically, so its presence means the frame is
complete. A rerun skips frames whose JSON is a valid "cuboids/1" file fitted with the same settings
(:meth:`FrameJob.is_complete`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

from cuboidcli.export.files import output_files, result_name
from cuboidcli.fitting.config import FitConfig
from cuboidcli.io.result import same_settings, saved_settings
from cuboidcli.scaleout import Outcome, failed

__all__ = ["FolderRecording", "FrameJob", "fit_file", "fitter_for", "folder_tasks"]


@dataclass(frozen=True)
class FrameJob:
    """Everything but the input file: how to read a frame, fit it and write its outputs. ``cuboids fit``
    fills one from its options and runs it for one frame (:meth:`load`, :meth:`fit`, :meth:`save`) or for
    each frame of a folder (:func:`folder_tasks`, :func:`fit_file`). Picklable: it is sent to worker
    processes and Ray tasks, which build their :class:`~cuboidcli.api.Fitter` from it once."""

    config: FitConfig
    weights: str | None = None
    onnx: str | None = None
    intrinsics: str | None = None
    """``-K``: fx,fy,cx,cy or a JSON file (per frame name or one for all)."""
    preset: str | None = None
    """The camera preset (``--camera``): nyu, tum or scannet."""
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

    @property
    def from_rgb(self) -> bool:
        """The frames are photos whose depth a network estimates."""
        return self.depth_model is not None

    def fitter(self):
        """The job's :class:`~cuboidcli.api.Fitter`, built once per process (:func:`fitter_for`)."""
        return fitter_for(self.config, self.weights, self.onnx)

    def load(self, source: str | Path, image: str | Path | None = None):
        """Read one frame (:func:`cuboidcli.frame.load_frame`): ``source`` is its depth map (``image`` its
        photo, optional), or for a job :attr:`from_rgb` its photo. Raises InputError for unusable input."""
        from cuboidcli.frame import load_frame

        depth, image = (None, source) if self.from_rgb else (source, image)
        return load_frame(
            depth, image, self.intrinsics, self.preset, self.depth_scale, depth_model=self.depth_model
        )

    def fit(self, frame, progress=None):
        """Fit a frame :meth:`load` read; returns the :class:`~cuboidcli.api.Result`."""
        return self.fitter().fit_frame(frame, progress=progress)

    def save(self, result, out_json: str | Path) -> list[Path]:
        """Write the result's JSON and the outputs asked for beside it (the JSON last); returns the paths,
        the JSON first."""
        return result.save(
            out_json,
            glb=self.glb,
            ply=self.ply,
            overlay=self.overlay,
            with_points=self.with_points,
            scenes=self.scenes,
        )

    def outputs(self, out_json: Path) -> list[Path]:
        """The files a complete frame has, the JSON last (see :meth:`cuboidcli.api.Result.save`)."""
        return output_files(out_json, glb=self.glb, ply=self.ply, overlay=self.overlay, scenes=self.scenes)

    def is_complete(self, out_json: Path) -> bool:
        """The frame's outputs exist and its JSON is a valid "cuboids/1" result fitted with these settings."""
        saved = saved_settings(out_json, self.outputs(out_json))
        extra = {"weights": self.weights, "onnx": self.onnx}
        return saved is not None and same_settings(saved, self.config, extra)

    def in_folder(self, folder: Path) -> FrameJob:
        """The job for the frames of ``folder``: without ``-K``, the folder's cameras.json gives each frame's
        intrinsics."""
        cameras = Path(folder) / "cameras.json"
        if self.intrinsics is None and cameras.is_file():
            return replace(self, intrinsics=str(cameras))
        return self


@lru_cache(maxsize=4)
def fitter_for(config: FitConfig, weights: str | None, onnx: str | None):
    """The Fitter of a configuration, built once per process (a worker fits many frames with it)."""
    from cuboidcli.api import Fitter

    return Fitter(config, weights=weights, onnx=onnx, device=config.device)


def folder_tasks(job, files: list[Path], out_dir: Path, skip_existing: bool) -> tuple[list, list[Path]]:
    """The tasks (job, input file, result JSON) of a folder's inputs, their results in ``out_dir``, and the
    inputs left out with ``skip_existing`` because their outputs are complete (``job.is_complete``): the
    frames of a :class:`FrameJob` for :func:`fit_file`, the rooms of a
    :class:`~cuboidcli.room_folder.RoomJob` for :func:`~cuboidcli.room_folder.fit_room_file`."""
    tasks, skipped = [], []
    for f in files:
        out_json = Path(out_dir) / result_name(f)
        if skip_existing and job.is_complete(out_json):
            skipped.append(f)
        else:
            tasks.append((job, str(f), str(out_json)))
    return tasks, skipped


def fit_file(job: FrameJob, source: str, out_json: str) -> Outcome:
    """Fit one frame (``source``: a depth map, or an image with ``job.depth_model``) and write its outputs.
    Returns the Outcome (failed with a one-line message for unusable input); ``value`` is
    (cuboids, seconds, depth source)."""
    import warnings

    name = Path(source).name
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            job.fitter()  # the estimator first: bad weights fail before any input is read
            frame = job.load(source)
            result = job.fit(frame)
            job.save(result, out_json)
    except Exception as e:  # this frame fails; the run goes on
        return failed(name, e)
    notes = frame.notes + [str(w.message) for w in caught]
    value = (len(result.cuboids), result.info.timing_s["total"], frame.meta["depth_source"])
    return Outcome(name, "done", value=value, notes=notes)


class FolderRecording:
    """A folder's frames for one rerun recording: each finished frame's JSON is noted (and streamed to a
    viewer too when ``stream``, a :class:`~cuboidcli.export.rerun.RerunStream`, is given); the recording is
    written at the end, the frames in file order."""

    def __init__(self, stream=None) -> None:
        self.stream = stream

    def add(self, json_path: str) -> None:
        if self.stream is not None:
            self.stream.add(json_path)

    def write(self, path: Path, json_paths: list[Path]) -> Path:
        from cuboidcli.export.rerun import saved_inputs, write_rrd_frames
        from cuboidcli.io.result import read_result

        frames = []
        for p in json_paths:
            if p.is_file():
                result = read_result(p)
                frames.append((result, *saved_inputs(result)))
        return write_rrd_frames(frames, path)

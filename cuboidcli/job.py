"""One job for everything ``cuboids fit`` runs: :class:`Job` reads, fits and writes one input, a frame or
a room, and the same job fits every input of a folder, resumably, on any engine of
:mod:`cuboidcli.scaleout` (local processes or Ray): :func:`fit_task` is its one task.

An input's output is ``<out>/<name>_cuboids.json`` plus the files asked for (:mod:`cuboidcli.export.files`);
the JSON is written last and atomically, so its presence means the input is complete. A rerun skips inputs
whose JSON is a valid "cuboids/1" file fitted with the same settings (:meth:`Job.is_complete`).
"""

from __future__ import annotations

from dataclasses import dataclass, replace
from functools import lru_cache
from pathlib import Path

from cuboidcli.export.files import output_files, result_names
from cuboidcli.fitting.config import FitConfig
from cuboidcli.io.result import same_settings, saved_settings
from cuboidcli.load import SOURCES, LoadOptions
from cuboidcli.scaleout import Outcome, failed

__all__ = ["FolderRecording", "Job", "fit_task", "fitter_for", "folder_inputs", "folder_tasks"]


@dataclass(frozen=True)
class Job:
    """Everything but the input: how to read it, fit it and write its outputs. ``cuboids fit`` fills one
    from its options and runs it for one input (:meth:`load`, :meth:`fit`, :meth:`save`) or for each input
    of a folder (:func:`folder_tasks`, :func:`fit_task`). Picklable: it is sent to worker processes and
    Ray tasks, which build their :class:`~cuboidcli.api.Fitter` from it once (:func:`fitter_for`)."""

    config: FitConfig
    """The settings; those left unset take the input's kind's defaults (a room: up to 60 cuboids)."""
    weights: str | None = None
    onnx: str | None = None
    options: LoadOptions = LoadOptions()
    source: str | None = None
    """What the inputs are (:data:`cuboidcli.load.SOURCES`): ``depth`` maps, ``photo``s; None: told from
    each input (a room: a scan file or a sequence folder)."""
    outputs: tuple[str, ...] = ()
    """Output kinds written beside each JSON (:data:`cuboidcli.export.files.OUTPUTS`)."""
    with_points: bool = False

    @property
    def kind(self) -> str:
        """``frame`` or ``room``: the kind of the job's inputs."""
        return "room" if self.source is None else SOURCES[self.source]

    def fitter(self):
        """The job's :class:`~cuboidcli.api.Fitter`, built once per process (:func:`fitter_for`)."""
        return fitter_for(self.config, self.weights, self.onnx)

    def load(self, source: str | Path, image: str | Path | None = None, progress=None):
        """Read one input (:func:`cuboidcli.load.load`): a depth map (``image`` its photo), a photo, a
        scan file or a sequence folder. Raises InputError for unusable input."""
        from cuboidcli.load import load

        return load(source, self.options, image=image, source=self.source, progress=progress)

    def fit(self, inp, progress=None):
        """Fit an input :meth:`load` read; returns the :class:`~cuboidcli.result.Result`."""
        return self.fitter().fit_input(inp, self.options, progress=progress)

    def save(self, result, out_json: str | Path) -> list[Path]:
        """Write the result's JSON and the outputs asked for beside it (the JSON last); returns the paths,
        the JSON first."""
        return result.save(out_json, self.outputs, with_points=self.with_points)

    def run(
        self,
        source: str | Path,
        out_json: str | Path,
        image: str | Path | None = None,
        *,
        on_loaded=None,
        progress=None,
        fuse_progress=None,
    ):
        """Fit one input and write its outputs, the JSON last: the estimator first (bad weights fail before
        any input is read), then :meth:`load`, ``on_loaded(input)`` (to show its notes), :meth:`fit`
        (``progress(step, cuboids, gain)``) and :meth:`save`. Returns (result, paths written, JSON first).
        Raises InputError for unusable input."""
        fitter = self.fitter()
        inp = self.load(source, image, progress=fuse_progress)
        if on_loaded is not None:
            on_loaded(inp)
        result = fitter.fit_input(inp, self.options, progress=progress)
        return result, self.save(result, out_json)

    def expected(self, out_json: Path) -> list[Path]:
        """The files a complete result has, the JSON last. A room's overlays are named after the frames
        they are drawn on, known only once it is read: they are not listed."""
        kinds = [k for k in self.outputs if k != "overlay" or self.kind == "frame"]
        return output_files(out_json, kinds)

    def is_complete(self, out_json: Path) -> bool:
        """The input's outputs exist and its JSON is a valid "cuboids/1" result fitted with these settings
        (a setting an older result lacks counts at its default)."""
        saved = saved_settings(out_json, self.expected(out_json))
        if saved is None:
            return False
        extra = {"weights": self.weights, "onnx": self.onnx}
        config = self.config.for_kind(self.kind)
        # a room of a folder is a scan file or a sequence, read with the options that apply to it
        sources = (self.source,) if self.source is not None else ("scan", "sequence")
        saved_load = saved.get("load")
        same_load = any(
            (LoadOptions().to_dict(s) if saved_load is None else saved_load) == self.options.to_dict(s)
            for s in sources
        )
        return same_load and same_settings(saved, config, extra)

    def in_folder(self, folder: Path) -> Job:
        """The job for the frames of ``folder``: without ``-K``, the folder's cameras.json gives each frame's
        intrinsics."""
        cameras = Path(folder) / "cameras.json"
        if self.kind == "frame" and self.options.intrinsics is None and cameras.is_file():
            return replace(self, options=replace(self.options, intrinsics=str(cameras)))
        return self


@lru_cache(maxsize=4)
def fitter_for(config: FitConfig, weights: str | None, onnx: str | None):
    """The Fitter of a configuration, built once per process (a worker fits many inputs with it)."""
    from cuboidcli.api import Fitter

    return Fitter(config, weights=weights, onnx=onnx, device=config.device)


#: Of several scan files in a room's own sub-folder, the one ScanNet fits (its cleaned, decimated mesh).
SCANNET_MESH = "_vh_clean_2.ply"


def rooms_in(folder: Path, levels: int = 2) -> list[Path]:
    """The rooms of a folder, sorted: its scan files, its sub-folders laid out as sequences, and its
    sub-folders that hold a room's scan file (ScanNet's ``scans/scene0000_00/scene0000_00_vh_clean_2.ply``:
    the ``_vh_clean_2.ply`` of several, else the only one), one level deeper. A sub-folder with no scan file
    of its own is searched the same way while ``levels`` allows: ScanNet's root folder gives the rooms of
    its ``scans/``."""
    from cuboidcli.load.room import is_room_input

    rooms = []
    for p in sorted(Path(folder).iterdir()):
        if p.name.startswith("."):
            continue
        if is_room_input(p):
            rooms.append(p)
        elif p.is_dir():
            scans = sorted(
                q for q in p.iterdir() if q.is_file() and not q.name.startswith(".") and is_room_input(q)
            )
            preferred = [q for q in scans if q.name.endswith(SCANNET_MESH)]
            if len(preferred) == 1 or len(scans) == 1:
                rooms.append((preferred or scans)[0])
            elif not scans and levels > 1:
                rooms.extend(rooms_in(p, levels - 1))
    return rooms


def is_rooms_folder(path: Path) -> bool:
    """A folder of rooms (scan files, sequence sub-folders) and no images (which would make it a folder of
    frames)."""
    from cuboidcli.io.inputs import has_images

    return path.is_dir() and not has_images(path) and bool(rooms_in(path))


def folder_inputs(folder: Path, source: str | None) -> tuple[list[Path], int]:
    """The inputs of a folder for a job of ``source``: its depth maps, its photos (and how many other
    images were left out), or its rooms (None)."""
    from cuboidcli.io.inputs import depth_maps_in, photos_in

    if source == "photo":
        return photos_in(folder)
    if source == "depth":
        return depth_maps_in(folder)
    return rooms_in(folder), 0


def folder_tasks(job: Job, files: list[Path], out_dir: Path, skip_existing: bool) -> tuple[list, list[Path]]:
    """The tasks (job, input, result JSON) of a folder's inputs, their results in ``out_dir``, and the
    inputs left out with ``skip_existing`` because their outputs are complete (:meth:`Job.is_complete`)."""
    tasks, skipped = [], []
    for f, name in zip(files, result_names(files), strict=True):
        out_json = Path(out_dir) / name
        if skip_existing and job.is_complete(out_json):
            skipped.append(f)
        else:
            tasks.append((job, str(f), str(out_json)))
    return tasks, skipped


def fit_task(job: Job, source: str, out_json: str) -> Outcome:
    """Fit one input of a folder and write its outputs. Returns the Outcome (failed with a one-line message
    for unusable input: the run goes on); ``value`` is (cuboids, fitting seconds, what was fitted: a
    frame's depth source or a room's number of fitting points)."""
    import warnings

    from cuboidcli.io.atomic import OutputError

    name = Path(source).name
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            result, _ = job.run(source, out_json)
    except OutputError:  # a read-only or full output folder fails every input alike: the run stops
        raise
    except Exception as e:  # this input fails; the run goes on
        return failed(name, e)
    inp = result.input
    notes = inp.notes + [str(w.message) for w in caught]
    what = inp.meta.get("depth_source") if inp.kind == "frame" else result.info.n_points
    value = (len(result.cuboids), result.record.timing_s["total"], what)
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

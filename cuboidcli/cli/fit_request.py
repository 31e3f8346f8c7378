"""What ``cuboids fit`` was asked to do, typed: :class:`FitRequest`, made from the command's options, and
the checks that every option given applies to the input (an option a fit would not read is refused in
one line, exit 2, rather than dropped)."""

from __future__ import annotations

from dataclasses import dataclass, fields
from pathlib import Path

from cuboidcli.cli.common import fail
from cuboidcli.fitting.config import FitConfig
from cuboidcli.load import SOURCES, LoadOptions

#: FitConfig settings only one kind of input reads: given for the other, they are refused.
KIND_ONLY = {
    "voxel_m": "room",
    "object_fits": "room",
    "visibility": "room",
    "up": "room",
    "grid_step": "frame",
    "gravity_down": "frame",
}


@dataclass(frozen=True)
class Outputs:
    """Where and what to write: ``output`` (a JSON, or a folder for a folder's inputs), the output kinds
    (:data:`cuboidcli.export.files.OUTPUTS`), whether the GLB holds the points, and a live rerun stream."""

    output: Path | None = None
    kinds: tuple[str, ...] = ()
    with_points: bool = False
    rerun: bool = False
    quiet: bool = False


@dataclass(frozen=True)
class Run:
    """Where a folder's inputs run: ``workers`` local processes, or Ray (``ray`` "" = a local Ray, else the
    cluster's address; None = no Ray); ``skip_existing`` resumes."""

    workers: int = 1
    ray: str | None = None
    skip_existing: bool = True

    def describe(self) -> str:
        if self.ray is not None:
            return f"Ray at {self.ray}" if self.ray else "a local Ray"
        return f"{self.workers} processes" if self.workers > 1 else "this process"


@dataclass(frozen=True)
class FitRequest:
    """One ``cuboids fit``: the input (``path``, and a depth map's photo ``image``), what it is
    (``source``, :data:`cuboidcli.load.SOURCES`) and whether it is a folder of such inputs, the settings
    (only those given are set: the rest take the input's defaults), how to read it, the weights, the
    outputs and where it runs."""

    path: Path
    image: Path | None
    source: str | None
    """depth, photo, scan, sequence; None: a folder of rooms (each told from its files)."""
    folder: bool
    config: FitConfig
    given: frozenset[str]
    """The FitConfig settings the command line gave."""
    load: LoadOptions
    typed: frozenset[str]
    """The command's parameters the user typed, by name (also those left at their default value)."""
    weights: str | None
    onnx: str | None
    outputs: Outputs
    run: Run

    @property
    def kind(self) -> str:
        return "room" if self.source is None else SOURCES[self.source]

    def check(self) -> None:
        """One line and exit 2 for an option that does not apply to this input."""
        if self.config.solver == "onnx" and self.onnx is None:
            fail("--solver onnx needs --onnx solver.onnx (make one with cuboids export --onnx)")
        if self.onnx is not None and self.config.solver != "onnx":
            fail(f"--onnx {self.onnx}: the solver is {self.config.solver}; --onnx applies to --solver onnx")
        if (self.run.workers > 1 or self.run.ray is not None) and not self.folder:
            fail(
                "--workers and --ray fit the inputs of a folder: give a folder of depth maps, images or rooms"
            )
        what = "a room" if self.kind == "room" else "a depth map or a photo"
        for name in sorted(self.given):
            if KIND_ONLY.get(name, self.kind) != self.kind:
                fail(f"{_flag(name)} does not apply to {what}; leave it out")
        if self.kind == "room" and self.config.sampler == "learned":
            fail("--sampler learned weighs the pixels of a depth map; a room is fitted with sequential")
        if self.source is not None:
            sources: tuple[str, ...] = (self.source,)
        else:  # rooms: a folder's own kinds of room, else one room told from its files when loaded
            sources = _room_sources(self.path) if self.folder else ("scan", "sequence")
        default = LoadOptions()
        for f in fields(LoadOptions):
            value = getattr(self.load, f.name)
            if value == getattr(default, f.name):
                continue
            if not any(s in _applies(f.name) for s in sources):
                fail(f"{_flag(f.name)} does not apply to {what}; leave it out")
            if self.folder and self.source is None and not all(s in _applies(f.name) for s in sources):
                # a folder of scans and sequences: each room the option does not fit would fail on its own
                fits = "sequences" if "sequence" in _applies(f.name) else "scan files"
                fail(f"{_flag(f.name)} reads only the {fits} of the folder {self.path}; fit those apart")
        if self.source == "depth" and self.image is not None and self.image.is_dir():
            fail("IMAGE is a folder: give it without --depth (depth from the images) or use --depth FOLDER")
        if self.source == "depth" and self.image is not None and self.folder:
            fail("--depth FOLDER fits the folder's depth maps without their images; leave IMAGE out")
        self._check_typed(what)
        self._check_outputs(what)
        model = self.load.depth_model
        if self.folder and self.source == "photo" and model is not None and model.partial_depth is not None:
            fail("--partial-depth belongs to one image; it cannot align every image of a folder")

    def _check_typed(self, what: str) -> None:
        """An option typed for an input it does not apply to is refused, even at its default value."""
        sources = _sources(self)
        for name in sorted(self.typed):
            applies = TYPED_APPLIES.get(name)
            if applies is not None and not any(s in applies for s in sources):
                if applies == ("folder",):
                    fail(f"{_flag(name)} applies to a folder of inputs, not to one input; leave it out")
                fail(f"{_flag(name)} does not apply to {what}; leave it out")

    def _check_outputs(self, what: str) -> None:
        """Outputs the result cannot have are refused before anything is fitted (the table of outputs says
        which frame each is written for and what it needs)."""
        from cuboidcli.export.files import OUTPUTS

        frame = "world" if self.kind == "room" else "opencv"
        for kind in self.outputs.kinds:
            if frame not in OUTPUTS[kind].frames:
                fail(f"--{kind} is written for a depth map or a photo, not for {what}; leave it out")
        if self.source == "scan" and "overlay" in self.outputs.kinds:
            fail("--overlay draws a room's cuboids on its sequence's frames; a scan has none: leave it out")
        if self.outputs.rerun and self.kind == "room":
            fail(f"--rerun streams fitted frames, not {what}; write a recording of a frame with --rrd")
        if self.outputs.with_points and "glb" not in self.outputs.kinds:
            fail("--with-points adds the points to the GLB: give --glb too")


def _applies(name: str) -> tuple[str, ...]:
    from cuboidcli.load import APPLIES

    return APPLIES[name]


def _flag(name: str) -> str:
    from cuboidcli.cli.options import flags

    special = {
        "intrinsics": "-K",
        "depth_model": "--depth-model (and the depth-model options)",
        "skip_existing": "--skip-existing/--no-skip-existing",
    }
    if name in special:
        return special[name]
    if name in {f.name for f in fields(FitConfig)}:
        return flags(name).split("/")[0]
    return "--" + name.replace("_", "-")


#: The loading and run options of ``cuboids fit`` (by parameter name) and the inputs they apply to:
#: sources (:data:`cuboidcli.load.SOURCES`), or "folder" for a folder of inputs.
TYPED_APPLIES: dict[str, tuple[str, ...]] = {
    "intrinsics": ("depth", "photo", "sequence"),
    "camera": ("depth", "photo", "sequence"),
    "preset": ("depth", "photo", "sequence"),
    "depth_scale": ("depth", "photo", "sequence"),
    "unit": ("scan",),
    "every": ("sequence",),
    "skip_existing": ("folder",),
    **dict.fromkeys(
        ("depth_model", "depth_model_kind", "relative_scale", "relative_shift", "partial_depth",
         "camera_height", "onnx_preset", "depth_edges"),
        ("photo",),
    ),
}  # fmt: skip


def _room_sources(path: Path) -> tuple[str, ...]:
    """What the rooms at ``path`` are: a folder of rooms' ("scan" for its scan files, "sequence" for its
    sequence folders, in that order), else both (one room, told from its files when it is loaded)."""
    from cuboidcli.job import rooms_in

    if not path.is_dir() or _is_sequence(path):
        return ("scan", "sequence")
    rooms = rooms_in(path)
    kinds = tuple(k for k in ("scan", "sequence") if any((r.is_dir()) == (k == "sequence") for r in rooms))
    return kinds or ("scan", "sequence")


def _is_sequence(path: Path) -> bool:
    from cuboidcli.io.sequence import sequence_layout

    return sequence_layout(path) is not None


def _sources(request: FitRequest) -> tuple[str, ...]:
    """What the request's inputs can be: its source, a folder of rooms' scans and sequences, and "folder"."""
    sources = ("scan", "sequence") if request.source is None else (request.source,)
    return (*sources, "folder") if request.folder else sources

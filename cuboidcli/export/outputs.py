"""Every output kind, once: :data:`OUTPUTS` names each kind's files, its writer, the extra it needs, the
results it applies to and the input data it reads; :func:`write` writes the kinds asked for of a fitted
frame or room (:class:`~cuboidcli.export.fitted.Fitted`) beside ``<stem>.json``.

The lists of kinds elsewhere (``SCENES``, ``SCENE_EXTRAS``, ``WORLD_SCENES``, ``output_paths``, ...) are
views of this table, so a new kind is one entry here and a writer.
"""

from __future__ import annotations

import importlib
import importlib.util
from collections.abc import Callable, Iterable, Iterator, Mapping, MutableMapping
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cuboidcli.export.fitted import Fitted, View
from cuboidcli.io.atomic import OutputError

#: The result frames: a frame's OpenCV camera frame and a room's input frame, and what each result is.
FRAMES = {"opencv": "frame", "world": "room"}
BOTH = tuple(FRAMES)
#: The input points of a result, by frame: a frame's depth map, a room's points with their labels.
POINT_DATA = {"opencv": "depth", "world": "points"}
#: What each kind of input data is, for the messages that refuse an output without it.
DATA_NAMES = {
    "depth": "the depth map the result was fitted on",
    "points": "the room's input points and their cuboid labels",
    "views": "sequence frames to draw on (a scan has none)",
}
#: Data whose absence leaves the output out instead of refusing it: a room read from a scan has no frames
#: to draw on, and its overlays have always been left out, so that one request serves sequences and scans.
OPTIONAL_DATA = ("views",)


@dataclass(frozen=True)
class Output:
    """One output kind."""

    kind: str
    files: tuple[tuple[str, str], ...]
    """(key, suffix beside ``<stem>``) of each file, the main one first; the others are named after it."""
    writer: str
    """``module:function``, imported when used. A scene file's is ``writer(record, path, *, depth_m, rgb,
    points, point_colors) -> Path``; the others' ``writer(context, paths) -> {key: path}`` (a
    :class:`cuboidcli.export.writers.Context`, this kind's files)."""
    extra: tuple[str, str] | None
    """(module, extra): the library it needs and the ``cuboids[extra]`` that installs it; None: nothing."""
    frames: tuple[str, ...]
    """The result frames it is written for."""
    needs: Mapping[str, str] = field(default_factory=dict)
    """Per frame, the input data it cannot be written without (a key of :data:`DATA_NAMES`)."""
    scene: bool = False
    """A scene file in the z-up world of :mod:`cuboidcli.export.scene` (levelled by gravity)."""
    with_points: bool = False
    """``with_points`` adds the input's points to it, and then needs them (:data:`POINT_DATA`)."""
    view_file: str | None = None
    """A room's file per sequence frame it is drawn on, ``{frame}`` standing for the frame's name."""


# fmt: off
OUTPUTS: dict[str, Output] = {o.kind: o for o in (
    Output("glb", (("glb", ".glb"),),
           "cuboidcli.export.writers:glb", None, BOTH, with_points=True),
    Output("ply", (("points_ply", "_points.ply"), ("cuboids_ply", "_cuboids.ply")),
           "cuboidcli.export.writers:ply", None, BOTH, needs=POINT_DATA),
    # OBJ is in glTF axes of the camera frame; a room's input frame has no camera to turn it by
    Output("obj", (("obj", ".obj"), ("mtl", ".mtl")),
           "cuboidcli.export.writers:obj", None, ("opencv",)),
    Output("overlay", (("overlay", "_overlay.png"), ("labels", "_labels.png"),
                       ("labels_color", "_labels_color.png"), ("panel", "_panel.png")),
           "cuboidcli.export.writers:overlay", None, BOTH, needs={"world": "views"},
           view_file="_overlay_{frame}.png"),
    Output("html", (("html", ".html"),),
           "cuboidcli.export.html:write_html", ("plotly", "viz"), BOTH, scene=True),
    Output("mjcf", (("mjcf", "_mjcf.xml"),),
           "cuboidcli.export.mjcf:write_mjcf", ("mujoco", "sim"), BOTH, scene=True),
    Output("urdf", (("urdf", ".urdf"),),
           "cuboidcli.export.mjcf:write_urdf", None, BOTH, scene=True),
    Output("usd", (("usd", ".usda"),),
           "cuboidcli.export.usd:write_usd", ("pxr", "sim"), BOTH, scene=True),
    # a recording holds one pinhole camera at its pose: a room has no single camera
    Output("rrd", (("rrd", ".rrd"),),
           "cuboidcli.export.rerun:write_rrd", ("rerun", "viz"), ("opencv",), scene=True),
)}
# fmt: on

#: Scene files other tools open, by kind: (suffix beside ``<stem>``, writer module, writer function).
SCENES: dict[str, tuple[str, str, str]] = {
    o.kind: (o.files[0][1], *o.writer.split(":")) for o in OUTPUTS.values() if o.scene
}
#: Scene kinds whose files are in the z-up world frame (levelled by gravity when the fit had it).
WORLD_SCENES: tuple[str, ...] = tuple(SCENES)
#: The library each kind needs and the extra that installs it (None: nothing beyond cuboids).
EXTRAS: dict[str, tuple[str, str] | None] = {o.kind: o.extra for o in OUTPUTS.values()}


class KindView(MutableMapping):
    """The entries of ``source`` for ``kinds`` alone, reading and writing through: a view that callers may
    patch (tests replace an extra's module) changes what :func:`missing_extra` sees."""

    def __init__(self, source: dict, kinds: Iterable[str]):
        self._source, self._kinds = source, tuple(kinds)

    def __getitem__(self, kind):
        if kind not in self._kinds:
            raise KeyError(kind)
        return self._source[kind]

    def __setitem__(self, kind, value) -> None:
        if kind not in self._kinds:
            raise KeyError(f"{kind!r} is not one of {', '.join(self._kinds)}")
        self._source[kind] = value

    def __delitem__(self, kind) -> None:
        raise TypeError("the kinds of a view of the output table are fixed")

    def __iter__(self) -> Iterator[str]:
        return iter(self._kinds)

    def __len__(self) -> int:
        return len(self._kinds)

    def __repr__(self) -> str:
        return repr(dict(self))


#: :data:`EXTRAS` of the scene kinds.
SCENE_EXTRAS = KindView(EXTRAS, SCENES)


def _output(kind: str) -> Output:
    if kind not in OUTPUTS:
        raise ValueError(f"unknown output kind {kind!r}; choose {', '.join(OUTPUTS)}")
    return OUTPUTS[kind]


def missing_extra(kind: str) -> str | None:
    """A one-line message when the library output ``kind`` needs is not installed, else None."""
    _output(kind)
    if EXTRAS[kind] is None:
        return None
    module, extra = EXTRAS[kind]
    if importlib.util.find_spec(module) is None:
        return f"--{kind} needs the optional extra: pip install 'cuboids[{extra}]' ({module} is missing)"
    return None


def in_table_order(kinds: Iterable[str]) -> list[str]:
    """``kinds`` once each, in writing order; ValueError naming an unknown one."""
    if isinstance(kinds, str):  # one kind, not its letters
        kinds = (kinds,)
    asked = set()
    for kind in kinds:
        asked.add(_output(kind).kind)
    return [kind for kind in OUTPUTS if kind in asked]


def _has(result: Fitted, data: str) -> bool:
    if data == "depth":
        return result.depth_m is not None
    if data == "points":
        return result.points is not None and result.point_labels is not None
    return len(result.views) > 0 and result.record.camera is not None


def _check_frame_inputs(result: Fitted) -> None:
    """A frame's depth map and image must be the camera's size (the writers index one by the other)."""
    cam = result.record.camera
    if cam is None:
        raise ValueError("a frame's result needs its camera (the record's camera is null)")
    for what, image in (("depth map", result.depth_m), ("RGB image", result.rgb)):
        if image is not None and tuple(image.shape[:2]) != (cam.height, cam.width):
            raise ValueError(
                f"the {what} is {image.shape[1]}x{image.shape[0]} but the result's camera is "
                f"{cam.width}x{cam.height}; pass the {what} the result was fitted on"
            )


def kinds_for(
    result: Fitted, kinds: Iterable[str], *, with_points: bool = False
) -> tuple[list[str], list[str]]:
    """(the kinds of ``kinds`` that :func:`write` writes for ``result``, in writing order; one line per
    kind left out, saying why). Raises, naming the kind, for one that does not apply: ValueError (unknown,
    not for this result's frame, input data missing), ImportError (its optional extra is missing)."""
    frame = result.record.frame
    if frame not in FRAMES:
        raise ValueError(f"the result's frame is {frame!r}; expected one of {', '.join(FRAMES)}")
    todo, skipped = [], []
    for kind in in_table_order(kinds):
        o = OUTPUTS[kind]
        if frame not in o.frames:
            only = " and ".join(f"{FRAMES[f]}s" for f in o.frames)
            raise ValueError(f"{kind}: not written for a {FRAMES[frame]}'s result, only for {only}")
        needs = {o.needs[frame]: kind} if frame in o.needs else {}
        if with_points and o.with_points:
            needs.setdefault(POINT_DATA[frame], f"{kind} with points")
        missing = [data for data in needs if not _has(result, data)]
        for data in missing:
            if data not in OPTIONAL_DATA:
                raise ValueError(f"{needs[data]} needs {DATA_NAMES[data]}; the result has none")
        if missing:
            skipped.append(f"{kind}: left out, the {FRAMES[frame]} has no {DATA_NAMES[missing[0]]}")
            continue
        message = missing_extra(kind)
        if message:
            raise ImportError(message)
        todo.append(kind)
    if frame == "opencv" and todo:
        _check_frame_inputs(result)
    return todo, skipped


def result_stem(out_json: str | Path) -> Path:
    """``out/scene`` of ``out/scene.json``: what the files beside the result are named from."""
    p = Path(out_json)
    return p.with_name(p.name.removesuffix(".json"))


def overlay_views(views: list[View], count: int = 3) -> list[View]:
    """The frames a room's overlays are drawn on: the first, the last and evenly between."""
    n = len(views)
    if n == 0:
        return []
    return [views[i] for i in sorted({int(round(i)) for i in np.linspace(0, n - 1, min(count, n))})]


def named_after(kind: str, path: str | Path) -> dict[str, Path]:
    """The files of ``kind`` when its main file is ``path``: the others beside it, named after it with the
    main file's suffix taken off (``x.ply`` or ``x_points.ply`` -> ``x_cuboids.ply``)."""
    p = Path(path)
    base = _base(kind, p)
    files = OUTPUTS[kind].files
    return {key: p if i == 0 else Path(f"{base}{suffix}") for i, (key, suffix) in enumerate(files)}


def _base(kind: str, main: Path) -> Path:
    """``dir/x`` of the main file ``dir/x<marker>.<ext>`` (``dir/x.<ext>`` too) of ``kind``."""
    first = OUTPUTS[kind].files[0][1]
    marker = first[: first.rindex(".")]
    stem = main.stem
    if marker and stem.endswith(marker):
        stem = stem[: -len(marker)]
    return main.with_name(stem)


def kind_paths(
    kind: str, stem: str | Path | None, *, main: str | Path | None = None, views: list[View] | None = None
) -> dict[str, Path]:
    """The files of ``kind`` beside ``<stem>.json`` (or named after its ``main`` file), in writing order;
    for a room (``views`` given) with a per-frame file, one per frame it is drawn on."""
    o = OUTPUTS[kind]
    if main is None and stem is None:
        raise ValueError(f"{kind}: give the stem of the result or the path of the {kind} file")
    if views is not None and o.view_file is not None:
        base = stem if main is None else _base(kind, Path(main))
        return {
            f"{o.files[0][0]}_{v.name}": Path(f"{base}{o.view_file.format(frame=v.name)}")
            for v in overlay_views(views)
        }
    if main is not None:
        return named_after(kind, main)
    return {key: Path(f"{stem}{suffix}") for key, suffix in o.files}


def load_writer(kind: str):
    """The function that writes ``kind`` (imported now: it may need an optional extra)."""
    module, function = OUTPUTS[kind].writer.split(":")
    return getattr(importlib.import_module(module), function)


def write(
    result: Fitted,
    stem: str | Path | None,
    kinds: Iterable[str],
    *,
    with_points: bool = False,
    point_step: int | None = None,
    paths: Mapping[str, str | Path] | None = None,
    last: tuple[str | Path, Callable[[], dict[str, Path]]] | None = None,
) -> dict[str, Path]:
    """Write the outputs of ``kinds`` (keys of :data:`OUTPUTS`) of a fitted frame or room beside ``<stem>``
    (``out/scene`` for ``out/scene.json``; a trailing ``.json`` is dropped), in writing order; returns
    {file key: path}. Not the JSON: :func:`write_json_last` has it written last (``last``), so that where
    it exists every output is complete.

    ``with_points`` adds the input's points to the GLB; a frame's point clouds take every ``point_step``-th
    pixel (None: :func:`cuboidcli.export.writers.cloud_step`). ``paths`` {kind: main file} names files
    elsewhere than beside ``stem`` (their other files named after them). Every kind is checked before
    anything is written (:func:`kinds_for`); a room's overlays are left out when it has no frames to draw
    on, and a frame of a sequence whose depth cannot be read is passed over.

    ``last`` (path, write) writes one more file after the others (the result's JSON). A folder that cannot
    be written to raises :class:`~cuboidcli.io.atomic.OutputError`, and the files this call created are
    removed again.
    """
    from cuboidcli.export.writers import Context

    paths = dict(paths or {})
    todo, _ = kinds_for(result, [*kinds, *paths], with_points=with_points)
    if point_step is not None and point_step < 1:
        raise ValueError(f"the point step must be at least 1, got {point_step}")
    if stem is not None and Path(stem).suffix.lower() == ".json":
        stem = Path(stem).with_suffix("")
    views = result.views if result.record.frame == "world" else None
    planned = {kind: kind_paths(kind, stem, main=paths.get(kind), views=views) for kind in todo}
    context = Context(result, with_points=with_points, point_step=point_step)
    written: dict[str, Path] = {}
    targets = [Path(p) for files in planned.values() for p in files.values()]
    existed = {p for p in [*targets, *([Path(last[0])] if last else [])] if p.exists()}
    try:
        for kind in todo:
            writer = load_writer(kind)
            if OUTPUTS[kind].scene:
                ((key, path),) = planned[kind].items()
                written[key] = Path(writer(result.record, path, **context.scene_inputs()))
            else:
                written.update(writer(context, planned[kind]))
        if last is not None:
            written.update(last[1]())
    except OutputError:
        remove_new(written.values(), existed)
        raise
    return written


def remove_new(paths: Iterable[Path], existed: set[Path]) -> None:
    """Remove the files of ``paths`` that are not in ``existed``: a result that could not be written whole
    leaves none of its new files behind (files it replaced stay replaced; its JSON, written last, is not)."""
    for path in paths:
        if Path(path) not in existed:
            Path(path).unlink(missing_ok=True)


def write_json_last(
    result: Fitted,
    json_path: str | Path,
    kinds: Iterable[str] = (),
    *,
    with_points: bool = False,
    point_step: int | None = None,
) -> dict[str, Path]:
    """:func:`write` beside ``json_path``, then the "cuboids/1" JSON, atomically: its presence means every
    output of the result was written. Returns {file key: path}, ``"json"`` last."""
    from cuboidcli.io.result import write_result

    def json() -> dict[str, Path]:
        return {"json": write_result(json_path, result.record)}

    stem = result_stem(json_path)
    return write(result, stem, kinds, with_points=with_points, point_step=point_step, last=(json_path, json))

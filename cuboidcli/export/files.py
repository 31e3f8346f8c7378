"""The files ``cuboids fit`` writes, named here once: the result JSON of an input and the folder of a
folder's results when ``-o`` is not given, and beside a result ``<stem>.json`` the images, meshes and scene
files asked for (:func:`output_paths`, in the order they are written; the JSON comes last). The names of
the outputs come from the table of output kinds, :data:`cuboidcli.export.outputs.OUTPUTS`.
"""

from __future__ import annotations

from collections.abc import Iterable
from pathlib import Path

from cuboidcli.export.outputs import OUTPUTS, SCENES, in_table_order, kind_paths, named_after, result_stem

__all__ = [
    "FOLDER_RECORDING",
    "OUTPUTS",
    "SCENES",
    "frame_overlay_path",
    "image_paths",
    "output_files",
    "output_paths",
    "ply_paths",
    "result_name",
    "result_names",
    "result_stem",
    "results_folder",
    "scene_path",
]

#: A folder's frames in one rerun recording (``cuboids fit DIR --rrd``), in the folder of results.
FOLDER_RECORDING = "cuboids.rrd"


def result_name(source: str | Path) -> str:
    """The result JSON of an input: ``<stem>_cuboids.json`` for a file (a depth map, a photo, a scan),
    ``<name>_cuboids.json`` for a folder (a sequence)."""
    p = Path(source)
    return f"{p.name if p.is_dir() else p.stem}_cuboids.json"


def result_names(sources: Iterable[str | Path]) -> list[str]:
    """The result JSONs of a folder's inputs, one each: :func:`result_name`, except where inputs would share
    it: those are named by their whole file name (``a.png`` and ``a.npy``: ``a_png_cuboids.json``), then
    also by their folder and the one above while they still share (``scans/a/room.ply`` and
    ``scans/b/room.ply``: ``a_room_ply_cuboids.json``), and numbered if even that is shared. The same inputs
    always get the same names, so a rerun finds its results."""
    paths = [Path(s) for s in sources]
    names = [result_name(p) for p in paths]
    for level in range(3):
        shared = {n for n in names if names.count(n) > 1}
        for i, p in enumerate(paths):
            if names[i] in shared:
                parts = [*p.parent.parts[len(p.parent.parts) - level :], p.name.replace(".", "_")]
                names[i] = "_".join(parts) + "_cuboids.json"
    shared = {n for n in names if names.count(n) > 1}
    return [
        f"{n.removesuffix('_cuboids.json')}_{i}_cuboids.json" if n in shared else n
        for i, n in enumerate(names)
    ]


def results_folder(folder: str | Path) -> Path:
    """Where the results of a folder's frames or rooms go when no ``-o`` is given: ``<name>_cuboids``."""
    return Path(f"{Path(folder).name}_cuboids")


def scene_path(stem: str | Path, kind: str) -> Path:
    """Where ``cuboids fit --KIND`` writes scene ``kind`` of the result ``<stem>.json``."""
    return Path(f"{stem}{SCENES[kind][0]}")


def image_paths(overlay_path: str | Path) -> dict[str, Path]:
    """Where the images that accompany an overlay go: ``x.png`` -> x_labels.png, x_labels_color.png,
    x_panel.png (and ``x_overlay.png`` -> x_labels.png, ...)."""
    return named_after("overlay", overlay_path)


def ply_paths(points_path: str | Path) -> dict[str, Path]:
    """``x.ply`` holds the points and x_cuboids.ply the meshes (``x_points.ply`` -> x_cuboids.ply)."""
    return named_after("ply", points_path)


def output_paths(stem: str | Path, kinds: Iterable[str], *, views: list | None = None) -> dict[str, Path]:
    """The files beside the result ``<stem>.json`` for the outputs ``kinds`` (keys of
    :data:`~cuboidcli.export.outputs.OUTPUTS`), by file key, in the order they are written: ``glb``
    <stem>.glb; ``ply`` <stem>_points.ply and <stem>_cuboids.ply; ``obj`` <stem>.obj and <stem>.mtl;
    ``overlay`` <stem>_overlay.png, _labels.png, _labels_color.png, _panel.png, or for a room (its sequence
    frames ``views`` given) <stem>_overlay_<frame>.png on each frame it is drawn on; each scene kind at
    :func:`scene_path`."""
    paths: dict[str, Path] = {}
    for kind in in_table_order(kinds):
        paths.update(kind_paths(kind, stem, views=views))
    return paths


def frame_overlay_path(stem: str | Path, frame: str) -> Path:
    """A room's overlay drawn on its sequence's frame ``frame``, beside the result ``<stem>.json``."""
    return Path(f"{stem}{OUTPUTS['overlay'].view_file.format(frame=frame)}")


def output_files(out_json: str | Path, kinds: Iterable[str], *, views: list | None = None) -> list[Path]:
    """Every file of a complete result ``out_json`` with the outputs ``kinds`` (as :func:`output_paths`),
    the JSON last (it is written last, so where it exists the others do)."""
    return [*output_paths(result_stem(out_json), kinds, views=views).values(), Path(out_json)]

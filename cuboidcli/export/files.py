"""The files ``cuboids fit`` writes, named here once: the result JSON of an input and the folder of a
folder's results when ``-o`` is not given, and beside a result ``<stem>.json`` the images, meshes and scene
files asked for (:func:`output_paths`, in the order they are written; the JSON comes last)."""

from __future__ import annotations

from pathlib import Path

#: Scene files other tools open, by kind: the file name beside a result (``<stem>`` + this) that ``cuboids
#: fit --KIND`` writes, and the module and function that write one (imported when used: each needs an
#: optional extra).
SCENES: dict[str, tuple[str, str, str]] = {
    "html": (".html", "cuboidcli.export.html", "write_html"),
    "mjcf": ("_mjcf.xml", "cuboidcli.export.mjcf", "write_mjcf"),
    "urdf": (".urdf", "cuboidcli.export.mjcf", "write_urdf"),
    "usd": (".usda", "cuboidcli.export.usd", "write_usd"),
    "rrd": (".rrd", "cuboidcli.export.rerun", "write_rrd"),
}
#: A folder's frames in one rerun recording (``cuboids fit DIR --rrd``), in the folder of results.
FOLDER_RECORDING = "cuboids.rrd"


def result_name(source: str | Path) -> str:
    """The result JSON of an input: ``<stem>_cuboids.json`` for a file (a depth map, a photo, a scan),
    ``<name>_cuboids.json`` for a folder (a sequence)."""
    p = Path(source)
    return f"{p.name if p.is_dir() else p.stem}_cuboids.json"


def results_folder(folder: str | Path) -> Path:
    """Where the results of a folder's frames or rooms go when no ``-o`` is given: ``<name>_cuboids``."""
    return Path(f"{Path(folder).name}_cuboids")


def result_stem(out_json: str | Path) -> Path:
    """``out/scene`` of ``out/scene.json``: what the files beside the result are named from."""
    p = Path(out_json)
    return p.with_name(p.name.removesuffix(".json"))


def scene_path(stem: str | Path, kind: str) -> Path:
    """Where ``cuboids fit --KIND`` writes scene ``kind`` of the result ``<stem>.json``."""
    return Path(f"{stem}{SCENES[kind][0]}")


def _sibling(path: Path, drop_suffix: str, name: str, ext: str) -> Path:
    """``dir/<stem>_<name><ext>`` where a trailing ``_<drop_suffix>`` is removed from the stem first."""
    stem = path.stem
    if stem.endswith(f"_{drop_suffix}"):
        stem = stem[: -len(drop_suffix) - 1]
    return path.with_name(f"{stem}_{name}{ext}")


def image_paths(overlay_path: str | Path) -> dict[str, Path]:
    """Where the images that accompany an overlay go: ``x.png`` -> x_labels.png, x_labels_color.png,
    x_panel.png (and ``x_overlay.png`` -> x_labels.png, ...)."""
    p = Path(overlay_path)
    return {
        "overlay": p,
        "labels": _sibling(p, "overlay", "labels", ".png"),
        "labels_color": _sibling(p, "overlay", "labels_color", ".png"),
        "panel": _sibling(p, "overlay", "panel", ".png"),
    }


def ply_paths(points_path: str | Path) -> dict[str, Path]:
    """``x.ply`` holds the points and x_cuboids.ply the meshes (``x_points.ply`` -> x_cuboids.ply)."""
    p = Path(points_path)
    return {"points_ply": p, "cuboids_ply": _sibling(p, "points", "cuboids", ".ply")}


def output_paths(
    stem: str | Path,
    *,
    glb: bool = False,
    ply: bool = False,
    obj: bool = False,
    overlay: bool = False,
    scenes: tuple[str, ...] = (),
) -> dict[str, Path]:
    """The files beside the result ``<stem>.json`` for the outputs asked for, by kind, in the order they are
    written: ``glb`` <stem>.glb; ``ply`` <stem>_points.ply and <stem>_cuboids.ply; ``obj`` <stem>.obj and
    <stem>.mtl; ``overlay`` <stem>_overlay.png, _labels.png, _labels_color.png, _panel.png; each kind of
    ``scenes`` (:data:`SCENES`) at :func:`scene_path`."""
    paths: dict[str, Path] = {}
    if glb:
        paths["glb"] = Path(f"{stem}.glb")
    if ply:
        paths.update(ply_paths(f"{stem}_points.ply"))
    if obj:
        paths.update(obj=Path(f"{stem}.obj"), mtl=Path(f"{stem}.mtl"))
    if overlay:
        paths.update(image_paths(f"{stem}_overlay.png"))
    for kind in scenes:
        paths[kind] = scene_path(stem, kind)
    return paths


def frame_overlay_path(stem: str | Path, frame: str) -> Path:
    """A room's overlay drawn on its sequence's frame ``frame``, beside the result ``<stem>.json``."""
    return Path(f"{stem}_overlay_{frame}.png")


def output_files(
    out_json: str | Path, *, glb: bool, ply: bool, overlay: bool, scenes: tuple[str, ...]
) -> list[Path]:
    """Every file of a complete result ``out_json`` with these outputs, the JSON last (it is written last,
    so where it exists the others do)."""
    extra = output_paths(result_stem(out_json), glb=glb, ply=ply, overlay=overlay, scenes=scenes)
    return [*extra.values(), Path(out_json)]

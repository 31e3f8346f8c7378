"""Outputs people can open: GLB (Blender, three.js), PLY (MeshLab, CloudCompare), OBJ, PNG overlays, and
scene files (HTML, MJCF, URDF, USD, rerun).

One table, :data:`OUTPUTS` (:mod:`cuboidcli.export.outputs`), names every output kind; :func:`write` writes
the kinds asked for of a fitted frame or room (:class:`Fitted`) beside ``<stem>.json`` and
:func:`write_json_last` the JSON after them. :func:`write_outputs` and :func:`export_result` are
:func:`write` of a saved result's record with its depth map and image; :func:`write_scene` calls the
table's writer of one scene kind.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cuboidcli.export.files import image_paths, output_paths, ply_paths, scene_path
from cuboidcli.export.fitted import Fitted, FittedData, View, result_up
from cuboidcli.export.glb import OPENCV_TO_GLTF, gltf_points, node_matrix, node_name, write_glb
from cuboidcli.export.obj import write_obj
from cuboidcli.export.outputs import (
    EXTRAS,
    OUTPUTS,
    SCENE_EXTRAS,
    SCENES,
    WORLD_SCENES,
    Output,
    kinds_for,
    load_writer,
    missing_extra,
    write,
    write_json_last,
)
from cuboidcli.export.overlay import (
    RayCast,
    colorize_depth,
    colorize_labels,
    raycast,
    render_images,
    write_png,
)
from cuboidcli.export.ply import (
    assign_labels,
    depth_points,
    label_colors,
    write_cuboid_ply,
    write_point_ply,
)
from cuboidcli.export.writers import (
    MAX_CLOUD_PIXELS,
    cloud_step,
    frame_glb,
    frame_images,
    frame_ply,
)
from cuboidcli.io.result import FitResult

__all__ = [
    "EXTRAS",
    "MAX_CLOUD_PIXELS",
    "OPENCV_TO_GLTF",
    "OUTPUTS",
    "Fitted",
    "FittedData",
    "Output",
    "RayCast",
    "View",
    "assign_labels",
    "cloud_step",
    "colorize_depth",
    "colorize_labels",
    "depth_points",
    "export_result",
    "gltf_points",
    "image_paths",
    "kinds_for",
    "label_colors",
    "node_matrix",
    "node_name",
    "output_paths",
    "ply_paths",
    "raycast",
    "render_images",
    "result_up",
    "SCENES",
    "SCENE_EXTRAS",
    "WORLD_SCENES",
    "missing_extra",
    "scene_path",
    "unlevelled_warning",
    "write",
    "write_cuboid_ply",
    "write_glb",
    "write_json_last",
    "write_obj",
    "write_outputs",
    "write_png",
    "write_point_ply",
    "write_result_glb",
    "write_result_images",
    "write_result_ply",
    "write_scene",
]


def unlevelled_warning(result: FitResult, kinds) -> str | None:
    """One line when scene files of ``kinds`` are asked for a result without gravity: they are then in the
    camera frame turned z-up, level only if the camera was."""
    if not any(k in WORLD_SCENES for k in kinds) or result.extras.get("world_from_camera") is not None:
        return None
    return (
        "the result has no gravity: scene files are in the camera frame turned z-up, level only if the "
        "camera was (fit with --align gravity or give --gravity gx,gy,gz)"
    )


def write_scene(
    kind: str, result: FitResult, path: str | Path, *, depth_m: np.ndarray | None = None, rgb=None
) -> Path:
    """Write scene ``kind`` (a key of :data:`SCENES`) of ``result`` to ``path``; ``depth_m`` and ``rgb``, when
    given, add the points and the image where the format holds them. ImportError (one line naming the
    extra) when the library it needs is missing; ValueError for a result it cannot hold."""
    if kind not in SCENES:
        raise ValueError(f"unknown scene kind {kind!r}; choose {', '.join(SCENES)}")
    return Path(load_writer(kind)(result, path, depth_m=depth_m, rgb=rgb))


def write_result_glb(
    result: FitResult,
    path: str | Path,
    *,
    depth_m: np.ndarray | None = None,
    rgb: np.ndarray | None = None,
    with_points: bool = False,
    point_step: int | None = None,
    labelled: tuple | None = None,
) -> Path:
    """GLB of the result's cuboids, with the input camera; with ``with_points`` also the depth map's points.
    A result with gravity gives a levelled scene (floor horizontal, +Y up).

    Points are coloured from ``rgb`` (H, W, 3) uint8 if given, else by their assigned cuboid. ``labelled``
    optionally passes (points, pixel indices, labels) already computed from the same depth map and step.
    """
    return frame_glb(
        result, path, depth_m=depth_m, rgb=rgb, with_points=with_points, point_step=point_step,
        labelled=labelled, up=result_up(result),
    )  # fmt: skip


def write_result_ply(
    result: FitResult,
    points_path: str | Path,
    depth_m: np.ndarray,
    *,
    point_step: int | None = None,
    cuboids_path: str | Path | None = None,
    labelled: tuple | None = None,
) -> dict[str, Path]:
    """Point cloud PLY coloured by assigned cuboid (grey none, black occluded) and the cuboid-mesh PLY
    (``cuboids_path``, default ``<name>_cuboids.ply`` beside the points)."""
    paths = ply_paths(points_path)
    if cuboids_path is not None:
        paths["cuboids_ply"] = Path(cuboids_path)
    return frame_ply(result, paths, depth_m, point_step=point_step, labelled=labelled)


def write_result_images(
    result: FitResult,
    overlay_path: str | Path,
    *,
    rgb: np.ndarray | None = None,
    depth_m: np.ndarray | None = None,
) -> dict[str, Path]:
    """Overlay, raw label image (0 = background, k + 1 = cuboid k), colourised labels and the panel."""
    return frame_images(result, image_paths(overlay_path), rgb=rgb, depth_m=depth_m)


def export_result(
    result: FitResult,
    *,
    glb_path: str | Path | None = None,
    ply_path: str | Path | None = None,
    obj_path: str | Path | None = None,
    overlay_path: str | Path | None = None,
    depth_m: np.ndarray | None = None,
    rgb: np.ndarray | None = None,
    with_points: bool = False,
    point_step: int | None = None,
    scenes: dict[str, str | Path] | None = None,
) -> dict[str, Path]:
    """Write each output whose path is given; returns {file key: path}. ``scenes``: {kind of
    :data:`SCENES`: path} of scene files (HTML viewer, simulator scenes, recordings) to write too.

    ``glb_path``: the GLB (``with_points`` adds the depth map's points). ``ply_path``: the point cloud PLY,
    with the cuboid meshes in ``<name>_cuboids.ply`` beside it (see :func:`ply_paths`; needs ``depth_m``).
    ``obj_path``: the OBJ and its .mtl. ``overlay_path``: the overlay PNG and, beside it, the label image,
    its colourised version and the panel (see :func:`image_paths`). ``depth_m`` (H, W) metres and ``rgb``
    (H, W, 3) uint8 must match the result's camera size; point clouds use every ``point_step``-th pixel
    (None: :func:`cloud_step`). This is :func:`write` with the files named one by one.
    Raises ValueError for missing or mismatched inputs, before writing anything.
    """
    given = {"glb": glb_path, "ply": ply_path, "obj": obj_path, "overlay": overlay_path, **(scenes or {})}
    paths = {kind: path for kind, path in given.items() if path is not None}
    fitted = FittedData.of_record(result, depth_m=depth_m, rgb=rgb)
    return write(fitted, None, (), with_points=with_points, point_step=point_step, paths=paths)


def write_outputs(
    result: FitResult,
    out_stem: str | Path,
    *,
    depth_m: np.ndarray | None = None,
    rgb: np.ndarray | None = None,
    glb: bool = False,
    ply: bool = False,
    obj: bool = False,
    overlay: bool = False,
    with_points: bool = False,
    point_step: int | None = None,
    scenes: tuple[str, ...] = (),
) -> dict[str, Path]:
    """Write the requested outputs next to ``out_stem`` (e.g. ``out/scene`` for ``out/scene.json``):
    :func:`write` of the record with its depth map and image, the kinds given as flags.

    ``glb``: <stem>.glb (``with_points`` adds the depth map's points). ``ply``: <stem>_points.ply and
    <stem>_cuboids.ply (needs ``depth_m``). ``obj``: <stem>.obj + <stem>.mtl. ``overlay``: <stem>_overlay.png,
    <stem>_labels.png, <stem>_labels_color.png, <stem>_panel.png. ``scenes``: kinds of :data:`SCENES`, each
    to :func:`scene_path`. ``depth_m`` (H, W) metres and ``rgb`` (H, W, 3) uint8 must match the result's
    camera size; points use every ``point_step``-th pixel (None: :func:`cloud_step`).
    Returns {file key: path}, as :func:`output_paths` names them.
    """
    flags = {"glb": glb, "ply": ply, "obj": obj, "overlay": overlay}
    kinds = [*(kind for kind, on in flags.items() if on), *scenes]
    fitted = FittedData.of_record(result, depth_m=depth_m, rgb=rgb)
    return write(fitted, out_stem, kinds, with_points=with_points, point_step=point_step)

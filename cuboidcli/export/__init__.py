"""Outputs people can open: GLB (Blender, three.js), PLY (MeshLab, CloudCompare), OBJ, PNG overlays, and
scene files (HTML, MJCF, URDF, USD, rerun).

One table, :data:`OUTPUTS` (:mod:`cuboidcli.export.outputs`), names every output kind; :func:`write` writes
the kinds asked for of a fitted frame or room (:class:`Fitted`) beside ``<stem>.json``, or each kind's
files where ``paths`` names them, and :func:`write_json_last` the JSON after them. A saved result is
written with :meth:`FittedData.of_record` (its record, with the depth map and image it was fitted on).
"""

from __future__ import annotations

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
from cuboidcli.export.writers import MAX_CLOUD_PIXELS, cloud_step
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
    "write_png",
    "write_point_ply",
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

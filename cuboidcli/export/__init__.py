"""Outputs people can open: GLB (Blender, three.js), PLY (MeshLab, CloudCompare), OBJ, PNG overlays.

Each exporter takes cuboids in the OpenCV camera frame and converts only on the way out. The entry points
here work on a whole :class:`~cuboidcli.io.result.FitResult`; :func:`write_outputs` is what ``cuboids fit``
calls to write everything next to the result JSON.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cuboidcli.export.files import SCENES, image_paths, output_paths, ply_paths, scene_path
from cuboidcli.export.glb import OPENCV_TO_GLTF, gltf_points, node_matrix, node_name, write_glb
from cuboidcli.export.obj import write_obj
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
from cuboidcli.io.result import FitResult

__all__ = [
    "OPENCV_TO_GLTF",
    "RayCast",
    "assign_labels",
    "colorize_depth",
    "colorize_labels",
    "depth_points",
    "export_result",
    "gltf_points",
    "image_paths",
    "label_colors",
    "node_matrix",
    "node_name",
    "ply_paths",
    "raycast",
    "render_images",
    "SCENES",
    "SCENE_EXTRAS",
    "missing_extra",
    "scene_path",
    "unlevelled_warning",
    "write_cuboid_ply",
    "write_glb",
    "write_obj",
    "write_outputs",
    "write_png",
    "write_result_glb",
    "write_result_images",
    "write_result_ply",
    "write_scene",
]


#: The library each scene kind needs and the extra that installs it (None: nothing beyond cuboids).
SCENE_EXTRAS: dict[str, tuple[str, str] | None] = {
    "html": ("plotly", "viz"),
    "mjcf": ("mujoco", "sim"),
    "urdf": None,
    "usd": ("pxr", "sim"),
    "rrd": ("rerun", "viz"),
}
#: Scene kinds whose files are in the z-up world frame (levelled by gravity when the fit had it).
WORLD_SCENES = ("html", "mjcf", "urdf", "usd", "rrd")


def missing_extra(kind: str) -> str | None:
    """A one-line message when the library scene ``kind`` needs is not installed, else None."""
    import importlib.util

    if SCENE_EXTRAS[kind] is None:
        return None
    module, extra = SCENE_EXTRAS[kind]
    if importlib.util.find_spec(module) is None:
        return f"--{kind} needs the optional extra: pip install 'cuboids[{extra}]' ({module} is missing)"
    return None


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
    import importlib

    if kind not in SCENES:
        raise ValueError(f"unknown scene kind {kind!r}; choose {', '.join(SCENES)}")
    _, module, function = SCENES[kind]
    writer = getattr(importlib.import_module(module), function)
    return Path(writer(result, path, depth_m=depth_m, rgb=rgb))


#: Point clouds of larger frames are subsampled to at most about this many pixels (a 640x480 frame's): a
#: 12 MP photo's every pixel would make a 200 MB file that no viewer opens smoothly.
MAX_CLOUD_PIXELS = 640 * 480


def cloud_step(shape: tuple[int, int], point_step: int | None = None) -> int:
    """The pixel step of an exported point cloud of an (H, W) depth map: ``point_step`` when given, else
    1 up to :data:`MAX_CLOUD_PIXELS` pixels and the smallest step that keeps the cloud within it above."""
    if point_step is not None:
        if point_step < 1:
            raise ValueError(f"the point step must be at least 1, got {point_step}")
        return int(point_step)
    h, w = shape
    step = 1
    while -(-h // step) * -(-w // step) > MAX_CLOUD_PIXELS:
        step += 1
    return step


def _labelled_points(
    result: FitResult, depth_m: np.ndarray, point_step: int | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Valid points (N, 3) m, their flat pixel indices (N,) and cuboid labels (N,) of a depth map."""
    if depth_m.shape != (result.camera.height, result.camera.width):
        raise ValueError(
            f"the depth map is {depth_m.shape[1]}x{depth_m.shape[0]} but the result's camera is "
            f"{result.camera.width}x{result.camera.height}; pass the depth map the result was "
            "fitted on"
        )
    points, pix = depth_points(depth_m, result.camera, cloud_step(depth_m.shape, point_step))
    return points, pix, assign_labels(points, result.cuboids, result.settings)


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
    points = colors = None
    if with_points:
        if depth_m is None:
            raise ValueError("the GLB point cloud needs the depth map; pass it or leave out the points")
        if rgb is not None and rgb.shape[:2] != depth_m.shape:
            raise ValueError("the RGB image and the depth map differ in size")
        if rgb is not None:
            points, pix = depth_points(depth_m, result.camera, cloud_step(depth_m.shape, point_step))
            colors = np.asarray(rgb, dtype=np.uint8).reshape(-1, 3)[pix]
        else:
            points, _, labels = labelled or _labelled_points(result, depth_m, point_step)
            colors = label_colors(labels)
    meta = {"schema": "cuboids/1", "camera": result.camera.to_dict(), "n_cuboids": len(result.cuboids)}
    return write_glb(
        path,
        result.cuboids,
        camera=result.camera,
        points=points,
        point_colors=colors,
        metadata=meta,
        up=result_up(result),
    )


def result_up(result: FitResult) -> np.ndarray | None:
    """The up direction (3,) in camera coordinates of a result with a "gravity" entry, else None."""
    down = (result.extras.get("gravity") or {}).get("down")
    if down is None:
        return None
    v = -np.asarray(down, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
        raise ValueError("the result's gravity.down must be three finite numbers, not all zero")
    return v / np.linalg.norm(v)


def write_result_ply(
    result: FitResult,
    points_path: str | Path,
    depth_m: np.ndarray,
    *,
    point_step: int | None = None,
    cuboids_path: str | Path | None = None,
    labelled: tuple | None = None,
) -> dict[str, Path]:
    """Point cloud PLY coloured by assigned cuboid (grey none, black occluded) and the cuboid-mesh PLY."""
    paths = ply_paths(points_path)
    if cuboids_path is not None:
        paths["cuboids_ply"] = Path(cuboids_path)
    points, _, labels = labelled or _labelled_points(result, depth_m, point_step)
    write_point_ply(paths["points_ply"], points, label_colors(labels))
    write_cuboid_ply(paths["cuboids_ply"], result.cuboids)
    return paths


def write_result_images(
    result: FitResult,
    overlay_path: str | Path,
    *,
    rgb: np.ndarray | None = None,
    depth_m: np.ndarray | None = None,
) -> dict[str, Path]:
    """Overlay, raw label image (0 = background, k + 1 = cuboid k), colourised labels and the panel."""
    images = render_images(result.camera, result.cuboids, rgb=rgb, depth_m=depth_m)
    paths = image_paths(overlay_path)
    for key, path in paths.items():
        write_png(path, images[key])
    return paths


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
    """Write each output whose path is given; returns {output kind: path}. ``scenes``: {kind of
    :data:`SCENES`: path} of scene files (HTML viewer, simulator scenes, recordings) to write too.

    ``glb_path``: the GLB (``with_points`` adds the depth map's points). ``ply_path``: the point cloud PLY,
    with the cuboid meshes in ``<name>_cuboids.ply`` beside it (see :func:`ply_paths`; needs ``depth_m``).
    ``obj_path``: the OBJ and its .mtl. ``overlay_path``: the overlay PNG and, beside it, the label image,
    its colourised version and the panel (see :func:`image_paths`). ``depth_m`` (H, W) metres and ``rgb``
    (H, W, 3) uint8 must match the result's camera size; point clouds use every ``point_step``-th pixel
    (None: :func:`cloud_step`).
    Raises ValueError for missing or mismatched inputs.
    """
    if ply_path is not None and depth_m is None:
        raise ValueError("the PLY point cloud needs the depth map the result was fitted on")
    if with_points and glb_path is not None and depth_m is None:
        raise ValueError("the GLB point cloud needs the depth map the result was fitted on")
    needs_labels = depth_m is not None and (
        ply_path is not None or (glb_path is not None and with_points and rgb is None)
    )
    labelled = _labelled_points(result, depth_m, point_step) if needs_labels else None
    written: dict[str, Path] = {}
    if glb_path is not None:
        written["glb"] = write_result_glb(
            result,
            glb_path,
            depth_m=depth_m,
            rgb=rgb,
            with_points=with_points,
            point_step=point_step,
            labelled=labelled,
        )
    if ply_path is not None:
        written.update(write_result_ply(result, ply_path, depth_m, point_step=point_step, labelled=labelled))
    if obj_path is not None:
        written["obj"], written["mtl"] = write_obj(obj_path, result.cuboids)
    if overlay_path is not None:
        written.update(write_result_images(result, overlay_path, rgb=rgb, depth_m=depth_m))
    for kind, path in (scenes or {}).items():
        written[kind] = write_scene(kind, result, path, depth_m=depth_m, rgb=rgb)
    return written


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
    """Write the requested outputs next to ``out_stem`` (e.g. ``out/scene`` for ``out/scene.json``).

    ``glb``: <stem>.glb (``with_points`` adds the depth map's points). ``ply``: <stem>_points.ply and
    <stem>_cuboids.ply (needs ``depth_m``). ``obj``: <stem>.obj + <stem>.mtl. ``overlay``: <stem>_overlay.png,
    <stem>_labels.png, <stem>_labels_color.png, <stem>_panel.png. ``scenes``: kinds of :data:`SCENES`, each
    to :func:`scene_path`. ``depth_m`` (H, W) metres and ``rgb``
    (H, W, 3) uint8 must match the result's camera size; points use every ``point_step``-th pixel (None:
    :func:`cloud_step`).
    Returns {output kind: path}; see :func:`export_result`.
    """
    base = Path(out_stem)
    if base.suffix.lower() == ".json":
        base = base.with_suffix("")
    paths = output_paths(base, glb=glb, ply=ply, obj=obj, overlay=overlay, scenes=scenes)
    return export_result(
        result,
        glb_path=paths.get("glb"),
        ply_path=paths.get("points_ply"),
        obj_path=paths.get("obj"),
        overlay_path=paths.get("overlay"),
        depth_m=depth_m,
        rgb=rgb,
        with_points=with_points,
        point_step=point_step,
        scenes={kind: paths[kind] for kind in scenes},
    )

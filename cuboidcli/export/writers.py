"""The writers of the outputs that differ between a frame and a room: GLB, PLY, OBJ and the overlays
(the scene files' writers take either result as it is). Each table writer of
:data:`cuboidcli.export.outputs.OUTPUTS` takes a :class:`Context` and the files of its kind, and returns
{file key: path}.

A frame's clouds are its depth map's valid pixels, in the OpenCV camera frame; a room's are its input
points in its own frame, coloured by the cuboid each belongs to.
"""

from __future__ import annotations

from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.export.fitted import Fitted
from cuboidcli.io.result import FitResult

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


def labelled_points(
    result: FitResult, depth_m: np.ndarray, point_step: int | None
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Valid points (N, 3) m, their flat pixel indices (N,) and cuboid labels (N,) of a depth map."""
    from cuboidcli.export.ply import assign_labels, depth_points

    if depth_m.shape != (result.camera.height, result.camera.width):
        raise ValueError(
            f"the depth map is {depth_m.shape[1]}x{depth_m.shape[0]} but the result's camera is "
            f"{result.camera.width}x{result.camera.height}; pass the depth map the result was "
            "fitted on"
        )
    points, pix = depth_points(depth_m, result.camera, cloud_step(depth_m.shape, point_step))
    return points, pix, assign_labels(points, result.cuboids, result.settings)


def frame_glb(
    result: FitResult,
    path: str | Path,
    *,
    depth_m: np.ndarray | None = None,
    rgb: np.ndarray | None = None,
    with_points: bool = False,
    point_step: int | None = None,
    labelled: tuple | None = None,
    up: np.ndarray | None = None,
) -> Path:
    """GLB of a frame's cuboids with its camera, levelled by ``up`` (camera coordinates) when given; with
    ``with_points`` also the depth map's points, coloured from ``rgb`` when given, else by cuboid
    (``labelled``: :func:`labelled_points` already computed for this map and step)."""
    from cuboidcli.export.glb import write_glb
    from cuboidcli.export.ply import depth_points, label_colors

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
            points, _, labels = labelled or labelled_points(result, depth_m, point_step)
            colors = label_colors(labels)
    meta = {"schema": "cuboids/1", "camera": result.camera.to_dict(), "n_cuboids": len(result.cuboids)}
    return write_glb(
        path, result.cuboids, camera=result.camera, points=points, point_colors=colors, metadata=meta, up=up
    )


def frame_ply(
    result: FitResult,
    paths: dict[str, Path],
    depth_m: np.ndarray,
    *,
    point_step: int | None = None,
    labelled: tuple | None = None,
) -> dict[str, Path]:
    """The depth map's points coloured by cuboid (grey none, black occluded) to ``paths["points_ply"]``,
    the cuboid meshes to ``paths["cuboids_ply"]``."""
    from cuboidcli.export.ply import label_colors, write_cuboid_ply, write_point_ply

    points, _, labels = labelled or labelled_points(result, depth_m, point_step)
    write_point_ply(paths["points_ply"], points, label_colors(labels))
    write_cuboid_ply(paths["cuboids_ply"], result.cuboids)
    return {key: Path(paths[key]) for key in ("points_ply", "cuboids_ply")}


def frame_images(
    result: FitResult,
    paths: dict[str, Path],
    *,
    rgb: np.ndarray | None = None,
    depth_m: np.ndarray | None = None,
) -> dict[str, Path]:
    """The overlay, the label image (0 background, k + 1 cuboid k), its colours and the panel, to the
    paths of their keys, drawn at most :data:`~cuboidcli.export.overlay.MAX_IMAGE_SIDE` pixels on the
    longer side; the size they were drawn at is recorded in the result (:func:`record_image_size`)."""
    from cuboidcli.export.overlay import MAX_IMAGE_SIDE, render_images, write_png

    images = render_images(result.camera, result.cuboids, rgb=rgb, depth_m=depth_m, max_side=MAX_IMAGE_SIDE)
    record_image_size(result, images["overlay"])
    written = {}
    for key, path in paths.items():
        written[key] = write_png(path, images.pop(key))  # each image freed once written
    return written


def record_image_size(result: FitResult, image: np.ndarray) -> None:
    """Note in the result (its ``overlay`` entry, written with its JSON) the size (width, height) its image
    outputs were drawn at and ``scale``, that width over the camera's. A large frame's are smaller than
    its camera's image W x H: their pixel (u, v) is the camera's ((u + 0.5) * W / width - 0.5,
    (v + 0.5) * H / height - 0.5)."""
    h, w = image.shape[:2]
    scale = w / result.camera.width if result.camera is not None and result.camera.width else 1.0
    result.extras["overlay"] = {"width": int(w), "height": int(h), "scale": round(float(scale), 6)}


def camera_cuboids(cuboids: list[Cuboid], world_from_camera: np.ndarray) -> list[Cuboid]:
    """World cuboids seen from a camera at ``world_from_camera`` (4, 4): the same boxes in its OpenCV
    coordinates."""
    inv = np.linalg.inv(world_from_camera)
    rot, t = inv[:3, :3], inv[:3, 3]
    return [
        Cuboid(rot @ c.center + t, c.half_size, rot @ c.rotation, c.inlier_gain, dict(c.extras), c.kind)
        for c in cuboids
    ]


@dataclass
class Context:
    """One :func:`cuboidcli.export.outputs.write` call: the result, its options, and what several outputs
    share, computed once (a frame's labelled points serve its PLY and its GLB's points)."""

    result: Fitted
    with_points: bool = False
    point_step: int | None = None

    @property
    def room(self) -> bool:
        return self.result.record.frame == "world"

    @cached_property
    def labelled(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """A frame's :func:`labelled_points`."""
        return labelled_points(self.result.record, self.result.depth_m, self.point_step)

    @cached_property
    def point_colors(self) -> np.ndarray:
        """(N, 3) uint8 a room's points coloured by cuboid."""
        from cuboidcli.export.ply import label_colors

        return label_colors(self.result.point_labels)

    def scene_inputs(self) -> dict:
        """The keywords of a scene file's writer: a frame's depth map and image; a room's points too."""
        r = self.result
        inputs = {"depth_m": r.depth_m, "rgb": r.rgb}
        if self.room and r.points is not None and r.point_labels is not None:
            inputs.update(points=r.points, point_colors=self.point_colors)
        return inputs


def glb(context: Context, paths: dict[str, Path]) -> dict[str, Path]:
    """A node per cuboid, levelled by the result's up (+Y up); a frame's has its camera, a room's its whole
    objects; ``with_points`` adds the input's points."""
    from cuboidcli.export.glb import write_glb

    r, record = context.result, context.result.record
    if not context.room:
        # an image colours the points itself: the labels are needed only without one
        labelled = context.labelled if context.with_points and r.rgb is None else None
        path = frame_glb(
            record, paths["glb"], depth_m=r.depth_m, rgb=r.rgb, with_points=context.with_points,
            point_step=context.point_step, labelled=labelled, up=r.up,
        )  # fmt: skip
        return {"glb": path}
    points, colors = (r.points, context.point_colors) if context.with_points else (None, None)
    meta = {"schema": "cuboids/1", "frame": "world", "n_cuboids": len(record.cuboids)}
    path = write_glb(
        paths["glb"], record.cuboids, points=points, point_colors=colors, metadata=meta, up=r.up,
        objects=r.objects,
    )  # fmt: skip
    return {"glb": path}


def ply(context: Context, paths: dict[str, Path]) -> dict[str, Path]:
    """The input's points coloured by cuboid and the cuboid meshes."""
    from cuboidcli.export.ply import write_cuboid_ply, write_point_ply

    r = context.result
    if not context.room:
        return frame_ply(r.record, paths, r.depth_m, labelled=context.labelled)
    return {
        "points_ply": write_point_ply(paths["points_ply"], r.points, context.point_colors),
        "cuboids_ply": write_cuboid_ply(paths["cuboids_ply"], r.record.cuboids),
    }


def obj(context: Context, paths: dict[str, Path]) -> dict[str, Path]:
    """The boxes as OBJ and their materials beside it."""
    from cuboidcli.export.obj import write_obj

    obj_path, mtl_path = write_obj(paths["obj"], context.result.record.cuboids)
    return {"obj": obj_path, "mtl": mtl_path}


def overlay(context: Context, paths: dict[str, Path]) -> dict[str, Path]:
    """A frame's overlay, label images and panel; a room's overlay on each of its frames named in
    ``paths`` (``overlay_<frame>``), the world cuboids seen from that frame's camera. A frame whose depth
    cannot be read any more is passed over."""
    r = context.result
    if not context.room:
        return frame_images(r.record, paths, rgb=r.rgb, depth_m=r.depth_m)
    from cuboidcli.export.overlay import MAX_IMAGE_SIDE, render_images, write_png
    from cuboidcli.io.depth import InputError, read_depth, read_rgb

    written = {}
    for view in r.views:
        key = f"overlay_{view.name}"
        if key not in paths:
            continue
        try:
            depth = read_depth(view.depth_path, view.depth_scale)
            rgb = read_rgb(view.rgb_path) if view.rgb_path is not None else None
        except InputError:
            continue
        if rgb is not None and rgb.shape[:2] != depth.shape:
            import cv2

            rgb = cv2.resize(rgb, (depth.shape[1], depth.shape[0]), interpolation=cv2.INTER_AREA)
        boxes = camera_cuboids(r.record.cuboids, view.world_from_camera)
        images = render_images(r.record.camera, boxes, rgb=rgb, depth_m=depth, max_side=MAX_IMAGE_SIDE)
        written[key] = write_png(paths[key], images["overlay"])
        record_image_size(r.record, images["overlay"])
    return written

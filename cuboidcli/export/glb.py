"""GLB (binary glTF 2.0) export: one node per cuboid, for Blender, three.js and other glTF viewers.

glTF is +Y up and looks down -Z; the OpenCV camera frame is +Y down and looks down +Z. The two differ by
``F = diag(1, -1, -1)``, a 180 degree turn about x (det +1, not a mirror), so a point ``x`` in camera
coordinates is ``F x`` in glTF. A cuboid's corner ``R (s * a) + c`` becomes ``(F R) (s * a) + F c``: the node
gets the proper rotation ``F R`` and the translation ``F c``, its mesh is the box with half-sizes ``a`` in the
cuboid's own frame, and the node's local axes are the cuboid's axes. Corner k of the mesh lands exactly on
``F @ Cuboid.corners()[k]``; triangle winding (outward normals) is preserved because F is a rotation.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid, palette_color
from cuboidcli.export.boxmesh import flat_box
from cuboidcli.geometry.gravity import smallest_rotation
from cuboidcli.io.atomic import atomic_write

#: OpenCV camera frame -> glTF frame (x right, y up, z backward).
OPENCV_TO_GLTF: np.ndarray = np.diag([1.0, -1.0, -1.0])


def node_name(cuboids: list[Cuboid], index: int) -> str:
    """Name of the node holding cuboid ``index`` of ``cuboids``: its scene name (:meth:`Cuboid.name`,
    floor_00, wall_01, object_02, ...), the same in every scene file."""
    return cuboids[index].name(index)


def level_rotation(up: np.ndarray | None) -> np.ndarray:
    """(3, 3) OpenCV camera frame -> glTF frame. Without ``up`` it is F; with the up direction ``up`` (3,)
    in camera coordinates (from gravity), F followed by the smallest rotation that turns F up onto glTF's
    +Y, so the floor is horizontal in viewers and the camera keeps its heading."""
    if up is None:
        return OPENCV_TO_GLTF.copy()
    u = OPENCV_TO_GLTF @ (np.asarray(up, dtype=np.float64) / np.linalg.norm(up))
    return smallest_rotation(u, np.array([0.0, 1.0, 0.0])) @ OPENCV_TO_GLTF


def gltf_points(points: np.ndarray, up: np.ndarray | None = None) -> np.ndarray:
    """Points (..., 3) in OpenCV camera coordinates -> the same points in glTF coordinates (metres),
    levelled when ``up`` is given (:func:`level_rotation`)."""
    return np.asarray(points, dtype=np.float64) @ level_rotation(up).T


def node_matrix(cuboid: Cuboid, up: np.ndarray | None = None) -> np.ndarray:
    """(4, 4) glTF node transform of a cuboid: rotation ``L R`` (det +1), translation ``L c`` with L the
    camera -> glTF rotation (F, or F levelled for ``up``: :func:`level_rotation`)."""
    lev = level_rotation(up)
    m = np.eye(4)
    m[:3, :3] = lev @ cuboid.rotation
    m[:3, 3] = lev @ cuboid.center
    return m


def node_extras(cuboid: Cuboid, index: int) -> dict:
    """JSON-safe cuboid parameters for the node's ``extras``, in the OpenCV camera frame (metres)."""
    return {
        "id": index,
        "frame": "opencv camera (x right, y down, z forward), metres; the node transform is glTF (y up)",
        **cuboid.parameters_json(),
        "color": list(palette_color(index)),
    }


#: Opacity of a room's whole-object boxes: the cuboids inside them stay visible.
OBJECT_ALPHA = 0.2


def build_scene(
    cuboids: list[Cuboid],
    points: np.ndarray | None = None,
    point_colors: np.ndarray | None = None,
    alpha: float = 1.0,
    metadata: dict | None = None,
    up: np.ndarray | None = None,
    objects: list[Cuboid] | None = None,
):
    """A trimesh Scene with nodes ``cuboid_00``... and, if ``points`` (N, 3) m is given, a ``points`` node.

    ``objects``: a room's whole-object boxes, as translucent grey nodes ``whole_object_00``...; each node's
    extras hold the box's parameters, ``cuboids``, the indices of the cuboids it is made of, and ``kind``
    (from the box's ``extras``: ``object``, ``door`` or ``sink``).

    ``points`` are in OpenCV camera coordinates; ``point_colors`` (N, 3) uint8 RGB (grey if None).
    ``alpha`` in (0, 1] is the boxes' opacity (glTF BLEND mode below 1). With ``up`` (3,), the up
    direction in camera coordinates, the scene is levelled (floor horizontal, glTF +Y up).
    """
    import trimesh
    from trimesh.visual.material import PBRMaterial

    scene = trimesh.Scene(metadata=dict(metadata or {}))
    for k, cub in enumerate(cuboids):
        rgb = np.array(palette_color(k), dtype=np.float64) / 255.0
        material = PBRMaterial(
            name=f"{node_name(cuboids, k)}_material",
            baseColorFactor=[float(rgb[0]), float(rgb[1]), float(rgb[2]), float(alpha)],
            metallicFactor=0.0,
            roughnessFactor=0.8,
            alphaMode="BLEND" if alpha < 1.0 else "OPAQUE",
            doubleSided=alpha < 1.0,
        )
        scene.add_geometry(
            _box_mesh(cub, material),
            node_name=node_name(cuboids, k),
            geom_name=node_name(cuboids, k),
            transform=node_matrix(cub, up),
            metadata=node_extras(cub, k),
        )
    for k, box in enumerate(objects or []):
        name = f"whole_object_{k:02d}"
        material = PBRMaterial(
            name=f"{name}_material",
            baseColorFactor=[0.6, 0.6, 0.6, OBJECT_ALPHA],
            metallicFactor=0.0,
            roughnessFactor=0.9,
            alphaMode="BLEND",
            doubleSided=True,
        )
        extras = {"id": k, "kind": str(box.extras.get("kind", "object"))}
        extras["cuboids"] = [int(i) for i in box.extras.get("cuboids", [])]
        scene.add_geometry(
            _box_mesh(box, material),
            node_name=name,
            geom_name=name,
            transform=node_matrix(box, up),
            metadata={**extras, **box.parameters_json()},
        )
    if points is not None and len(points) > 0:
        pts = np.asarray(points, dtype=np.float64).reshape(-1, 3)
        if point_colors is None:
            point_colors = np.full((len(pts), 3), 160, dtype=np.uint8)
        rgba = np.concatenate(
            [
                np.asarray(point_colors, dtype=np.uint8).reshape(-1, 3),
                np.full((len(pts), 1), 255, dtype=np.uint8),
            ],
            axis=1,
        )
        cloud = trimesh.PointCloud(gltf_points(pts, up).astype(np.float32), colors=rgba)
        scene.add_geometry(
            cloud,
            node_name="points",
            geom_name="points",
            metadata={"frame": "vertices are glTF coordinates (y up, z backward), metres"},
        )
    return scene


def _box_mesh(box: Cuboid, material):
    """A flat-shaded trimesh of ``box`` in its own frame (its node's transform places it), in ``material``."""
    import trimesh

    vertices, faces, normals = flat_box(box.half_size)
    return trimesh.Trimesh(
        vertices=vertices,
        faces=faces,
        vertex_normals=normals,
        process=False,
        visual=trimesh.visual.TextureVisuals(material=material),
    )


def _add_camera(tree: dict, camera: Camera, up: np.ndarray | None = None) -> None:
    """Append a perspective camera node at the origin looking down -Z (the input camera in glTF), turned
    with the scene when it is levelled (``up``).

    glTF cameras have no principal point, so an off-centre (cx, cy) is not represented.
    """
    tree.setdefault("cameras", []).append(
        {
            "name": "input_camera",
            "type": "perspective",
            "perspective": {
                "aspectRatio": float(camera.width) / float(camera.height),
                "yfov": 2.0 * math.atan(camera.height / (2.0 * camera.fy)),
                "znear": 0.01,
            },
        }
    )
    node = {"name": "input_camera", "camera": len(tree["cameras"]) - 1}
    if up is not None:  # the camera's own axes in the levelled frame: L F^T (column-major matrix)
        m = np.eye(4)
        m[:3, :3] = level_rotation(up) @ OPENCV_TO_GLTF.T
        node["matrix"] = [float(v) for v in m.T.reshape(-1)]
    tree["nodes"].append(node)
    tree["scenes"][0]["nodes"].append(len(tree["nodes"]) - 1)


def write_glb(
    path: str | os.PathLike,
    cuboids: list[Cuboid],
    *,
    camera: Camera | None = None,
    points: np.ndarray | None = None,
    point_colors: np.ndarray | None = None,
    alpha: float = 1.0,
    metadata: dict | None = None,
    up: np.ndarray | None = None,
    objects: list[Cuboid] | None = None,
) -> Path:
    """Write cuboids (and optionally points (N, 3) m, OpenCV frame, and a room's whole-object boxes
    ``objects``, see :func:`build_scene`) as a GLB file, atomically.

    With ``camera`` a glTF camera node named ``input_camera`` is added at the origin, so viewers can look
    through the input camera. With ``up`` (the up direction in camera coordinates, from gravity) the scene
    is levelled: the floor is horizontal and +Y is up. Returns ``path``.
    """
    from trimesh.exchange.gltf import export_glb

    if not 0.0 < alpha <= 1.0:
        raise ValueError(f"alpha must be in (0, 1], got {alpha}")
    meta = {"generator": "cuboids", "frame": "glTF = diag(1, -1, -1) * OpenCV camera frame, metres"}
    if up is not None:
        meta["frame"] = "glTF levelled by gravity (+Y up) = L * OpenCV camera frame, metres"
        meta["gltf_from_camera"] = [[float(v) for v in row] for row in level_rotation(up)]
    meta.update(metadata or {})
    scene = build_scene(cuboids, points, point_colors, alpha=alpha, metadata=meta, up=up, objects=objects)
    post = None if camera is None else (lambda tree: _add_camera(tree, camera, up))
    data = export_glb(scene, include_normals=True, tree_postprocessor=post)
    return atomic_write(path, lambda p: p.write_bytes(data))

"""The world frame and the names every scene file shares (GLB node names, HTML viewer, simulator scenes).

A result is fitted in the OpenCV camera frame (x right, y down, z forward, metres). Scene files want a
world frame with z up: the result's ``world_from_camera`` (levelled by gravity, origin at the camera, x
the camera's heading made horizontal) when the fit had gravity; otherwise the camera frame turned z-up
(x right, y forward, z up), which is level only when the camera was, so callers warn. Boxes are named by
:meth:`cuboidcli.cuboid.Cuboid.name` (floor_00, wall_01, object_02), the same in every file.
"""

from __future__ import annotations

import numpy as np

from cuboidcli.cuboid import palette_color
from cuboidcli.io.result import FitResult

#: OpenCV camera axes -> z-up axes without gravity: x stays, the optical axis becomes y, -y (up) becomes z.
CAMERA_TO_ZUP = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])


def world_from_camera(result: FitResult) -> tuple[np.ndarray, bool]:
    """((4, 4) camera -> world, z up, metres; whether it is levelled by gravity). ValueError for a
    ``world_from_camera`` entry that is not a rotation."""
    # a scan's or a sequence's result is in its input's frame: its levelled world is recorded the same way
    known = result.extras.get("world_from_input" if result.frame == "world" else "world_from_camera")
    if known is None:
        pose = np.eye(4)
        pose[:3, :3] = CAMERA_TO_ZUP
        return pose, False
    m = np.asarray(known, dtype=np.float64)
    pose = np.eye(4)
    if m.shape == (4, 4):
        pose = m.copy()
    elif m.shape == (3, 3):
        pose[:3, :3] = m
    else:
        raise ValueError(f"the result's world_from_camera has shape {m.shape}; expected (4, 4) or (3, 3)")
    rot = pose[:3, :3]
    if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-4) or np.linalg.det(rot) < 0:
        raise ValueError("the result's world_from_camera is not a rotation (with a translation)")
    return pose, True


def world_boxes(result: FitResult) -> list[tuple[str, np.ndarray, np.ndarray, np.ndarray, tuple]]:
    """Every cuboid in the world frame: (name, centre (3,), half-sizes (3,), rotation (3, 3) with the
    box's axes as columns, RGBA colour of the overlays), in the result's order. ValueError for a cuboid of
    zero (or non-finite) size, which no simulator or viewer can hold."""
    pose, _ = world_from_camera(result)
    rot, t = pose[:3, :3], pose[:3, 3]
    boxes = []
    for i, c in enumerate(result.cuboids):
        name = c.name(i)
        if not (np.all(np.isfinite(c.half_size)) and np.all(c.half_size > 0)):
            raise ValueError(
                f"cuboid {name} has size {2 * c.half_size} m; every side must be a positive length"
            )
        rgba = (*palette_color(i), 255)
        boxes.append((name, rot @ c.center + t, c.half_size.copy(), rot @ c.rotation, rgba))
    return boxes


def camera_pose_world(result: FitResult) -> np.ndarray:
    """(4, 4) the input camera's pose in the world frame (its OpenCV axes as the rotation's columns)."""
    pose, _ = world_from_camera(result)
    return pose.copy()

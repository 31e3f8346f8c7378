"""export/scene.py: the z-up world frame and the names all scene files share."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.export.scene import CAMERA_TO_ZUP, camera_pose_world, world_boxes, world_from_camera
from cuboidcli.geometry.gravity import given_gravity
from cuboidcli.io.result import FitResult

CAM = Camera(60.0, 60.0, 31.5, 23.5, 64, 48)


def _result(extras=None, half=(0.5, 0.02, 0.5)):
    boxes = [Cuboid([0.0, 1.4, 3.0], [2.0, 0.02, 2.0], np.eye(3), kind="floor"),
             Cuboid([0.3, 1.0, 2.5], half, np.eye(3))]  # fmt: skip
    return FitResult(camera=CAM, cuboids=boxes, extras=extras or {})


def test_without_gravity_the_camera_frame_is_turned_z_up():
    pose, levelled = world_from_camera(_result())
    assert not levelled and np.array_equal(pose[:3, :3], CAMERA_TO_ZUP)
    name, center, half, rot, rgba = world_boxes(_result())[0]
    assert name == "floor_00" and np.allclose(center, [0.0, 3.0, -1.4])  # 1.4 m below the camera
    assert np.allclose(rot, CAMERA_TO_ZUP) and rgba[3] == 255
    assert [b[0] for b in world_boxes(_result())] == ["floor_00", "object_01"]


def test_with_gravity_the_results_levelled_frame_is_used():
    tilted = given_gravity((0.0, 0.9, 0.3))  # a camera pitched down
    extras = {"world_from_camera": tilted.world_from_camera().tolist()}
    pose, levelled = world_from_camera(_result(extras))
    assert levelled and np.allclose(pose, tilted.world_from_camera())
    down_world = pose[:3, :3] @ tilted.down
    assert np.allclose(down_world, [0.0, 0.0, -1.0], atol=1e-9)
    assert np.allclose(camera_pose_world(_result(extras)), pose)
    # corners map exactly: the world box's corners are the camera box's corners moved by the pose
    box = _result(extras).cuboids[1]
    _, c, h, r, _ = world_boxes(_result(extras))[1]
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)])
    assert np.allclose(c + (signs * h) @ r.T, box.corners() @ pose[:3, :3].T + pose[:3, 3])


def test_zero_size_boxes_and_bad_frames_are_refused():
    with pytest.raises(ValueError, match="cuboid object_01 has size"):
        world_boxes(_result(half=(0.5, 0.0, 0.5)))
    with pytest.raises(ValueError, match="not a rotation"):
        world_from_camera(_result({"world_from_camera": (2 * np.eye(4)).tolist()}))
    assert world_boxes(FitResult(camera=CAM, cuboids=[])) == []

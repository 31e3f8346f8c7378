"""The "cuboids/1" frames: a frame's camera coordinates, or a room's world frame (camera null for a scan)."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.io.result import FitResult, check_result_json


def _doc(frame: str, camera):
    box = Cuboid(np.zeros(3), np.full(3, 0.5), np.eye(3), kind="floor")
    return FitResult(camera, [box], frame=frame).to_json()


def test_a_world_result_without_a_camera_round_trips():
    d = _doc("world", None)
    assert d["frame"] == "world" and d["camera"] is None
    back = FitResult.from_json(d)
    assert back.frame == "world" and back.camera is None and back.cuboids[0].kind == "floor"


def test_a_world_result_keeps_its_sequence_camera():
    back = FitResult.from_json(_doc("world", Camera.preset("tum")))
    assert back.frame == "world" and back.camera.fx == 525.0


@pytest.mark.parametrize(
    "frame, camera, message",
    [("opencv", None, "needs its camera"), ("lidar", Camera.preset("nyu"), "unsupported frame 'lidar'")],
)
def test_bad_frames_are_named(frame, camera, message):
    with pytest.raises(ValueError, match=message):
        check_result_json(_doc(frame, camera))

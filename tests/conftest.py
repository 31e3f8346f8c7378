import math
from pathlib import Path

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def yaw(angle: float) -> np.ndarray:
    """Rotation about the camera's y axis (vertical in the OpenCV frame)."""
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])


def simple_room() -> list[Cuboid]:
    """Floor, back wall, left wall, a cabinet and a rotated box; camera at the origin, y down."""
    eye = np.eye(3)
    return [
        Cuboid([0.0, 1.45, 2.75], [1.9, 0.05, 1.75], eye, extras={"category": "floor"}),
        Cuboid([0.0, -0.1, 4.55], [1.9, 1.5, 0.05], eye, extras={"category": "wall"}),
        Cuboid([-1.95, -0.1, 2.75], [0.05, 1.5, 1.75], eye, extras={"category": "wall"}),
        Cuboid([1.2, 0.9, 3.9], [0.4, 0.5, 0.3], eye, extras={"category": "cabinet"}),
        Cuboid([-0.5, 1.1, 3.0], [0.5, 0.3, 0.4], yaw(0.4), extras={"category": "box"}),
    ]


@pytest.fixture(scope="session")
def nyu_camera() -> Camera:
    return Camera.preset("nyu")


@pytest.fixture(scope="session")
def room_depth(nyu_camera):
    """Noise-free depth (480, 640) in metres of :func:`simple_room`, ray cast exactly."""
    from cuboidcli.synth.render import render_boxes

    depth, instance = render_boxes(simple_room(), nyu_camera)
    return depth, instance


@pytest.fixture()
def room_png(tmp_path, room_depth):
    import cv2

    path = tmp_path / "room_depth.png"
    cv2.imwrite(str(path), np.round(room_depth[0] * 1000).astype(np.uint16))
    return path

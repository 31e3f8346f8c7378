import math
from pathlib import Path

import numpy as np
import pytest
import torch

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid

SHARED_DATA = Path(__file__).resolve().parents[2] / "shared" / "data"


def fit_named(depth_m, camera, config=None, *, weights=None, **parts):
    """:func:`cuboidcli.fitting.pipeline.fit_depth` with the solver and sampler ``config`` names, built by
    :mod:`cuboidcli.factories` (the learned ones from ``weights``), unless ``parts`` gives them."""
    from cuboidcli.factories import make_sampler, make_solver
    from cuboidcli.fitting.config import FitConfig
    from cuboidcli.fitting.pipeline import fit_depth

    config = config or FitConfig()
    if "solver" not in parts:
        parts["solver"] = make_solver(config, weights, None, config.device)
    if "sampler" not in parts:
        parts["sampler"] = make_sampler(config.sampler, weights, config.device)
    return fit_depth(depth_m, camera, config, **parts)


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


@pytest.fixture()
def one_thread():
    """torch on one thread for the test (``pytestmark = pytest.mark.usefixtures("one_thread")``): tiny
    networks run fastest so, and two threads crawl when the CPU is shared."""
    before = torch.get_num_threads()
    torch.set_num_threads(1)
    yield
    torch.set_num_threads(before)


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


def write_room_dataset(root: Path, camera: Camera, rgb: bool = False) -> list[str]:
    """Four frames of :func:`simple_room` seen from slightly shifted cameras, in the dataset layout (depth in
    mm, optionally a shaded RGB image), split 3 train / 1 val. Returns the frame names."""
    import json

    import cv2

    from cuboidcli.io.dataset import write_cameras
    from cuboidcli.synth.render import render_boxes

    (root / "depth").mkdir(parents=True)
    if rgb:
        (root / "rgb").mkdir()
    names = [f"{i:06d}" for i in range(4)]
    for i, name in enumerate(names):
        shift = np.array([0.1 * i - 0.15, 0.0, 0.05 * i])
        boxes = [Cuboid(c.center + shift, c.half_size, c.rotation) for c in simple_room()]
        depth, _ = render_boxes(boxes, camera)
        cv2.imwrite(str(root / "depth" / f"{name}.png"), np.round(depth * 1000).astype(np.uint16))
        if rgb:
            shade = np.clip(255 - depth * 40, 0, 255).astype(np.uint8)
            cv2.imwrite(str(root / "rgb" / f"{name}.png"), np.stack([shade, shade // 2, 255 - shade], -1))
    write_cameras(root, {name: camera for name in names})
    (root / "splits.json").write_text(json.dumps({"train": names[:3], "val": names[3:]}))
    return names


@pytest.fixture
def rerun_cli(tmp_path, monkeypatch) -> str:
    """The `rerun` command of this environment, with its usage analytics switched off in a configuration
    folder of the test's own: the tests never let it contact anything beyond this machine."""
    import shutil
    import subprocess
    import sys

    pytest.importorskip("rerun")
    cli = shutil.which("rerun") or str(Path(sys.executable).with_name("rerun"))
    monkeypatch.setenv("XDG_CONFIG_HOME", str(tmp_path / "config"))
    subprocess.run([cli, "analytics", "disable"], capture_output=True, check=True)
    return cli

"""MJCF and URDF scenes loaded by MuJoCo itself: a fitted room holds a dropped ball on its floor and on the
box standing on it, and every box comes back where the JSON puts it (corners within 1 mm)."""

from __future__ import annotations

import numpy as np
import pytest

import cuboidcli as cb
from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.export.mjcf import rpy, write_mjcf, write_urdf
from cuboidcli.export.scene import world_boxes, world_from_camera
from cuboidcli.io.result import FitResult

mujoco = pytest.importorskip("mujoco")
SIGNS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)


@pytest.fixture(scope="module")
def room(room_depth, nyu_camera):
    depth, _ = room_depth
    camera = cb.Camera(nyu_camera.fx, nyu_camera.fy, nyu_camera.cx, nyu_camera.cy)
    return cb.fit(depth, camera, seed=0, hypotheses=256, max_cuboids=5, device="cpu").record


def _drop(scene_xml, start) -> np.ndarray:
    """Heights of a free 10 cm ball dropped from ``start`` (world, m), over 3 s of simulation."""
    spec = mujoco.MjSpec.from_file(str(scene_xml))
    body = spec.worldbody.add_body(name="ball", pos=[float(v) for v in start])
    body.add_freejoint()
    body.add_geom(type=mujoco.mjtGeom.mjGEOM_SPHERE, size=[0.05, 0, 0], mass=0.2)
    model = spec.compile()
    data = mujoco.MjData(model)
    heights = []
    while data.time < 3.0:
        mujoco.mj_step(model, data)
        heights.append(data.qpos[2])
    return np.array(heights), data.qvel[:3].copy()


def _top(box) -> tuple[np.ndarray, float]:
    _, center, half, rot, _ = box
    corners = center + (SIGNS * half) @ rot.T
    return center, float(corners[:, 2].max())


def test_a_ball_rests_on_the_floor_and_on_the_box(room, tmp_path):
    path = write_mjcf(room, tmp_path / "room.xml")
    assert world_from_camera(room)[1]  # the fit had gravity: a levelled scene
    boxes = world_boxes(room)
    floor = next(b for b in boxes if b[0].startswith("floor"))
    # the box standing on the floor (camera frame centre (-0.5, 1.1, 3.0))
    on_floor = [i for i, c in enumerate(room.cuboids) if np.linalg.norm(c.center - [-0.5, 1.1, 3.0]) < 0.15]
    box = boxes[on_floor[0]]
    assert box[0].startswith("object")
    for target in (floor, box):
        center, top = _top(target)
        start = (center[0] + 0.05, center[1] + 0.05, top + 1.0)
        heights, velocity = _drop(path, start)
        assert heights.min() > top  # its centre never goes below the surface: it does not fall through
        assert heights[-1] == pytest.approx(top + 0.05, abs=0.02) and np.abs(velocity).max() < 0.05


def test_mjcf_and_urdf_boxes_come_back_where_the_json_puts_them(room, tmp_path):
    want = {name: c + (SIGNS * h) @ r.T for name, c, h, r, _ in world_boxes(room)}
    for writer, name in ((write_mjcf, "room.xml"), (write_urdf, "room.urdf")):
        model = mujoco.MjModel.from_xml_path(str(writer(room, tmp_path / name)))
        data = mujoco.MjData(model)
        mujoco.mj_forward(model, data)
        assert model.ngeom == len(want)
        matched = set()
        for g in range(model.ngeom):
            rot = data.geom_xmat[g].reshape(3, 3)
            corners = data.geom_xpos[g] + (SIGNS * model.geom_size[g]) @ rot.T
            # the same box: every corner of the loaded geom is a corner of one JSON box (any order)
            error = {
                n: np.linalg.norm(corners[:, None] - c[None], axis=2).min(axis=1).max()
                for n, c in want.items()
            }
            best = min(error, key=error.get)
            assert error[best] < 1e-3, (writer.__name__, g, best, error[best])
            gname = mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g)
            assert gname in (None, best)  # MJCF geoms carry the scene names; MuJoCo's URDF reader drops them
            matched.add(best)
        assert matched == set(want)
    mj = mujoco.MjModel.from_xml_path(str(tmp_path / "room.xml"))
    assert mj.ncam == 1 and mujoco.mj_id2name(mj, mujoco.mjtObj.mjOBJ_CAMERA, 0) == "input_camera"


def test_an_empty_result_is_an_empty_scene_and_a_flat_box_is_refused(tmp_path):
    cam = Camera(60.0, 60.0, 31.5, 23.5, 64, 48)
    empty = FitResult(camera=cam, cuboids=[])
    assert mujoco.MjModel.from_xml_path(str(write_mjcf(empty, tmp_path / "e.xml"))).ngeom == 0
    assert mujoco.MjModel.from_xml_path(str(write_urdf(empty, tmp_path / "e.urdf"))).ngeom == 0
    flat = FitResult(camera=cam, cuboids=[Cuboid([0, 0, 2], [0.2, 0.0, 0.3], np.eye(3))])
    for writer in (write_mjcf, write_urdf):
        with pytest.raises(ValueError, match="object_00 has size"):
            writer(flat, tmp_path / "f.out")
        assert not (tmp_path / "f.out").exists()


def test_rpy_turns_back_into_the_rotation():
    rng = np.random.default_rng(1)
    for _ in range(20):
        r = np.linalg.qr(rng.normal(size=(3, 3)))[0]
        r *= np.sign(np.linalg.det(r))
        roll, pitch, yaw = rpy(r)
        rx = np.array([[1, 0, 0], [0, np.cos(roll), -np.sin(roll)], [0, np.sin(roll), np.cos(roll)]])
        ry = np.array([[np.cos(pitch), 0, np.sin(pitch)], [0, 1, 0], [-np.sin(pitch), 0, np.cos(pitch)]])
        rz = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
        assert np.allclose(rz @ ry @ rx, r, atol=1e-9)

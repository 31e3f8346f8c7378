"""Gravity / Manhattan-frame estimation and upright, long-slab winners (geometry/gravity.py,
fitting/winner.py)."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.config import FitConfig
from cuboidcli.geometry.gravity import (
    estimate_gravity,
    given_gravity,
    manhattan_rotation,
    upright_rotation,
)
from cuboidcli.geometry.rotations import axis_angle_to_matrix
from cuboidcli.synth import render_boxes
from tests.conftest import fit_named


def _rot(axis_angle) -> np.ndarray:
    return axis_angle_to_matrix(torch.tensor(axis_angle, dtype=torch.float64)).numpy()


def _room(pitch_deg: float, roll_deg: float, yaw_deg: float = 25.0):
    """Floor, two perpendicular walls and a cabinet, seen by a camera 1.5 m above the floor, pitched down
    and rolled. Returns (cuboids in camera coordinates, up in camera coordinates)."""
    # world: z up; camera looks along world +y; world_from_camera maps camera axes (x right, y down,
    # z forward) to world (x, -z, y) before the camera's pitch, roll and the room's yaw
    base = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])
    tilt = _rot([np.deg2rad(pitch_deg), 0, 0]) @ _rot([0, 0, np.deg2rad(roll_deg)])
    world_from_cam = _rot([0, 0, np.deg2rad(yaw_deg)]) @ base @ tilt
    cam_pos = np.array([0.0, 0.0, 1.5])
    world_boxes = [
        (np.array([0.0, 2.5, -0.025]), np.array([3.0, 3.0, 0.025])),  # floor
        (np.array([0.0, 5.5, 1.4]), np.array([3.0, 0.025, 1.4])),  # back wall
        (np.array([-2.5, 2.5, 1.4]), np.array([0.025, 3.0, 1.4])),  # left wall
        (np.array([1.0, 4.0, 0.5]), np.array([0.5, 0.3, 0.5])),  # cabinet
    ]
    cam_from_world = world_from_cam.T
    cuboids = [Cuboid(cam_from_world @ (c - cam_pos), a, cam_from_world.copy()) for c, a in world_boxes]
    return cuboids, cam_from_world @ np.array([0.0, 0.0, 1.0])


@pytest.mark.parametrize("pitch,roll", [(-20.0, 0.0), (-35.0, 6.0), (-8.0, -4.0)])
def test_gravity_of_a_rendered_room_is_within_half_a_degree(nyu_camera, pitch, roll):
    cuboids, up = _room(pitch, roll)
    depth, _ = render_boxes(cuboids, nyu_camera, noise=True, seed=3)
    g = estimate_gravity(nyu_camera.backproject(depth, 8))
    assert g is not None and g.source == "estimated"
    err = np.rad2deg(np.arccos(np.clip(g.up @ up, -1, 1)))
    assert err < 0.5, err
    assert np.allclose(g.frame.T @ g.frame, np.eye(3), atol=1e-9)
    assert g.frame[:, 0] @ g.up == pytest.approx(1.0)
    assert 0.3 < g.confidence <= 1.0


def test_a_frontal_wall_alone_gives_no_gravity(nyu_camera):
    wall = Cuboid(np.array([0.0, 0.0, 2.0]), np.array([3.0, 3.0, 0.02]), np.eye(3))
    depth, _ = render_boxes([wall], nyu_camera, noise=True)
    assert estimate_gravity(nyu_camera.backproject(depth, 8)) is None


def test_given_gravity_is_normalised_and_checked():
    g = given_gravity([0.0, 2.0, 0.0])
    assert np.allclose(g.down, [0, 1, 0]) and np.allclose(g.up, [0, -1, 0]) and g.source == "given"
    for bad in ([0, 0, 0], [1, np.nan, 0], [1, 2]):
        with pytest.raises(ValueError, match="gravity"):
            given_gravity(bad)


def test_upright_rotation_keeps_yaw_and_handedness():
    up = np.array([0.0, -1.0, 0.0])
    tilted = _rot([0.0, 0.4, 0.0]) @ _rot([0.1, 0.0, -0.05])  # yaw 0.4 rad, then a small tilt
    r = upright_rotation(tilted, up)
    assert np.linalg.det(r) == pytest.approx(1.0)
    assert np.allclose(r.T @ r, np.eye(3), atol=1e-12)
    assert abs(r[:, 1] @ up) == pytest.approx(1.0)  # the axis nearest vertical is now vertical
    # the yaw about the vertical is kept: the x axis stays in the same horizontal direction
    h = tilted[:, 0] - (tilted[:, 0] @ up) * up
    assert r[:, 0] @ (h / np.linalg.norm(h)) > 0.999


def test_manhattan_rotation_is_the_nearest_signed_permutation():
    axes = _rot([0.0, 0.3, 0.0])
    perm = axes[:, [2, 0, 1]] * np.array([1.0, -1.0, -1.0])
    assert np.linalg.det(perm) == pytest.approx(1.0)
    noisy = _rot([0.05, -0.08, 0.03]) @ perm
    assert np.allclose(manhattan_rotation(noisy, axes), perm, atol=1e-12)


def test_aligned_fit_gives_upright_boxes_and_keeps_the_free_fits_gain(nyu_camera):
    cuboids, up = _room(-25.0, 4.0)
    depth, _ = render_boxes(cuboids, nyu_camera, noise=True, seed=5)
    base = FitConfig(hypotheses=512, max_cuboids=4, seed=0, slab_max_m=4.0)
    _, free = fit_named(depth, nyu_camera, base)
    for mode in ("gravity", "manhattan"):
        boxes, info = fit_named(depth, nyu_camera, replace(base, align=mode))
        assert info.align == mode and info.gravity is not None
        assert len(boxes) == len(info.aligned) >= 3
        # the floor and the walls are aligned (a leftover wall piece may stay free when an aligned box
        # would explain much less of it); aligned boxes have an axis within 0.5 degrees of the vertical
        assert info.aligned[:2] == [mode, mode]
        for box, kind in zip(boxes, info.aligned, strict=True):
            if kind != "free":
                assert np.abs(box.rotation.T @ up).max() > np.cos(np.deg2rad(0.5))
        assert sum(info.gains) > 0.97 * sum(free.gains)
    # manhattan boxes share the room's axes: their rotations differ by signed permutations only
    boxes, _ = fit_named(depth, nyu_camera, replace(base, align="manhattan"))
    rel = boxes[0].rotation.T @ boxes[1].rotation
    assert np.allclose(np.abs(rel).max(0), 1.0, atol=1e-6)


def test_without_gravity_an_aligned_fit_stays_free_and_says_so(nyu_camera):
    wall = Cuboid(np.array([0.0, 0.0, 2.0]), np.array([3.0, 3.0, 0.02]), np.eye(3))
    depth, _ = render_boxes([wall], nyu_camera, noise=True)
    boxes, info = fit_named(depth, nyu_camera, FitConfig(hypotheses=256, align="gravity"))
    assert info.align == "free" and info.gravity is None and boxes
    assert len(info.warnings) == 1 and "--gravity" in info.warnings[0]
    # a given gravity is used as it is
    boxes, info = fit_named(
        depth, nyu_camera, FitConfig(hypotheses=256, align="gravity", gravity_down=(0.0, 1.0, 0.0))
    )
    assert info.align == "gravity" and info.gravity.source == "given" and not info.warnings
    assert np.abs(boxes[0].rotation.T @ np.array([0.0, -1.0, 0.0])).max() == pytest.approx(1.0)


def test_long_slabs_let_one_cuboid_span_a_wall_longer_than_two_a_max(nyu_camera):
    # a 7 m wall at 3 m, seen at a slant so it spans the image
    rot = _rot([0.0, 0.5, 0.0])
    wall = Cuboid(np.array([0.0, 0.0, 3.0]), np.array([3.5, 1.2, 0.02]), rot)
    depth, _ = render_boxes([wall], nyu_camera)
    base = FitConfig(hypotheses=256, max_cuboids=1, local_fraction=1.0, seed=2)
    short, _ = fit_named(depth, nyu_camera, replace(base, slab_max_m=None))
    long_, _ = fit_named(depth, nyu_camera, replace(base, slab_max_m=4.0))
    assert short[0].half_size.max() <= base.a_max + 1e-6
    assert long_[0].half_size.max() > base.a_max + 0.2
    assert long_[0].half_size.min() < 0.1  # still a slab


def test_levelled_glb_puts_up_on_gltf_y_and_keeps_the_heading():
    from cuboidcli.export.glb import OPENCV_TO_GLTF, level_rotation, node_matrix

    assert np.array_equal(level_rotation(None), OPENCV_TO_GLTF)
    up = np.array([0.05, -0.95, -0.3])
    up /= np.linalg.norm(up)
    lev = level_rotation(up)
    assert np.linalg.det(lev) == pytest.approx(1.0)
    assert np.allclose(lev @ up, [0.0, 1.0, 0.0], atol=1e-12)
    # the camera still looks the same way, only pitched and rolled level: forward stays in the -z half
    assert (lev @ np.array([0.0, 0.0, 1.0]))[2] < -0.9
    floor = Cuboid(np.array([0.0, 1.5, 3.0]), np.array([2.0, 2.0, 0.01]), upright_rotation(np.eye(3), up))
    m = node_matrix(floor, up)
    assert np.allclose(np.abs(m[:3, :3]).max(1), 1.0, atol=1e-9)  # axis-aligned in the levelled scene


def test_world_from_camera_is_z_up():
    g = given_gravity([0.0, 0.9, 0.3])
    m = g.world_from_camera()
    assert np.allclose(m[:3, :3] @ g.up, [0.0, 0.0, 1.0])
    assert np.allclose(m[:3, :3] @ m[:3, :3].T, np.eye(3))
    assert np.linalg.det(m[:3, :3]) == pytest.approx(1.0)

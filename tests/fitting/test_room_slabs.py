"""Walls, floor and ceiling on the room's axes (fitting/shell.py, fitting/align.py): which slabs are the
room's shell, the plane most of a bent wall's points lie on, trimming a turned wall off a doorway, and the
slab's normal matched first when it is turned onto the room's axes."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from cuboidcli.fitting.align import Alignment, align_winner
from cuboidcli.fitting.refit import plane_sweep
from cuboidcli.fitting.shell import is_room_slab
from cuboidcli.fitting.winner import shrink_cuboid
from cuboidcli.geometry.gravity import manhattan_rotation
from cuboidcli.synth import render_boxes
from tests.conftest import simple_room
from tests.fitting.test_winner_shape import _box, _ctx

UP = np.array([0.0, -1.0, 0.0])  # camera y points down
ROOM_AXES = np.stack([UP, [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], 1)


def _rx(deg: float) -> np.ndarray:
    """Rotation about the camera's x axis (a wall leaning towards or away from the camera)."""
    t = np.deg2rad(deg)
    return np.array([[1.0, 0.0, 0.0], [0.0, np.cos(t), -np.sin(t)], [0.0, np.sin(t), np.cos(t)]])


def _wall(z: float, x=(-1.5, 1.5), y=(-1.2, 1.2), step=0.04, tilt_deg=0.0) -> np.ndarray:
    """Points of a wall facing the camera at depth z, leaning by ``tilt_deg`` about the x axis."""
    xs, ys = np.meshgrid(np.arange(*x, step), np.arange(*y, step))
    p = np.stack([xs.ravel(), ys.ravel(), np.zeros(xs.size)], 1)
    return p @ _rx(tilt_deg).T + [0.0, 0.0, z]


def _floor(y: float = 0.9, x=(-1.5, 1.5), z=(1.5, 4.3), step=0.05) -> np.ndarray:
    xs, zs = np.meshgrid(np.arange(*x, step), np.arange(*z, step))
    return np.stack([xs.ravel(), np.full(xs.size, y), zs.ravel()], 1)


def test_the_room_shell_has_nothing_beyond_it(nyu_camera):
    depth, _ = render_boxes(simple_room(), nyu_camera)
    pts = nyu_camera.backproject(depth, 8).reshape(-1, 3)
    pts = pts[pts[:, 2] > 0].astype(np.float64)
    eye = np.eye(3)
    # floor (top face at y = 1.4), back wall (front face at z = 4.5), left wall (inner face at x = -1.9)
    assert is_room_slab(pts, [0.0, 1.4, 2.75], [1.9, 0.005, 1.75], eye)
    assert is_room_slab(pts, [0.0, -0.1, 4.5], [1.9, 1.5, 0.005], eye)
    assert is_room_slab(pts, [-1.9, -0.1, 2.75], [0.005, 1.5, 1.75], eye)
    # the cabinet's front has the back wall 0.9 m behind it, its top the floor 1 m below it
    assert not is_room_slab(pts, [1.2, 0.9, 3.6], [0.4, 0.5, 0.005], eye)
    assert not is_room_slab(pts, [1.2, 0.4, 3.9], [0.4, 0.005, 0.3], eye)
    # and a box that is not a slab is never part of the shell
    assert not is_room_slab(pts, [0.0, -0.1, 4.55], [1.9, 1.5, 1.0], eye)


def test_the_sweep_finds_the_plane_most_open_points_lie_on():
    near, far = _wall(4.5, x=(-1.5, 0.3)), _wall(4.7, x=(-0.3, 1.5))  # 60 % / 40 % of a stepped wall
    pts = np.concatenate([near, far])
    state = np.zeros(len(pts))
    got = plane_sweep(pts, state, pts, np.eye(3), 2)
    assert len(got) == len(near) and np.allclose(got[:, 2], 4.5)
    # points already explained are not counted: then the far part is the best plane
    state[: len(near)] = 1.0
    got = plane_sweep(pts, state, pts, np.eye(3), 2)
    assert len(got) == len(far) and np.allclose(got[:, 2], 4.7)


def test_a_wall_turned_over_a_doorway_is_trimmed_off_it():
    wall = _wall(4.5, x=(-1.5, 0.5))
    door = _wall(6.5, x=(0.9, 1.5), y=(-1.2, 1.2))  # seen through a doorway right of the wall
    pts = torch.from_numpy(np.concatenate([wall, door]))
    state = torch.zeros(len(pts), dtype=torch.float64)
    ctx = _ctx(pts, state)
    covering = ctx.score(_box([0.0, 0.0, 4.5], [1.5, 1.2, 0.01], np.eye(3)))  # covers the doorway
    shrunk = shrink_cuboid(covering, ctx)
    c2, a2 = shrunk.box.center, shrunk.box.half
    # the points seen through the doorway no longer count against it
    assert shrunk.gain > covering.gain + 0.5 * len(door)
    right_edge = float(c2[0, 0] + a2[0, 0])
    assert 0.45 < right_edge < 0.9  # it ends between the wall's end and the doorway
    assert float(c2[0, 0] - a2[0, 0]) == pytest.approx(-1.5)  # the left edge stays
    assert float(a2[0, 2]) == pytest.approx(0.01)  # and so does the thickness


def test_a_slab_normal_is_matched_first():
    """Matched most certain axis first, a slab's in-plane axis can take the room axis its normal is
    nearest to, turning the slab onto its edge; matched first, the normal goes to its nearest axis."""
    rng = np.random.default_rng(3)
    rots = [np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(200)]
    rots = [q * np.sign(np.linalg.det(q)) for q in rots]  # proper rotations
    edge_on = 0
    for rot in rots:
        nearest = int(np.argmax(np.abs(ROOM_AXES.T @ rot[:, 2])))
        slab = manhattan_rotation(rot, ROOM_AXES, first=2)
        assert np.allclose(slab.T @ slab, np.eye(3)) and np.linalg.det(slab) == pytest.approx(1.0)
        assert abs(slab[:, 2] @ ROOM_AXES[:, nearest]) == pytest.approx(1.0)
        free = manhattan_rotation(rot, ROOM_AXES)
        edge_on += abs(free[:, 2] @ ROOM_AXES[:, nearest]) < 0.5
    assert edge_on > 0  # the case the slab order is for does occur


def test_a_leaning_far_wall_stands_on_the_room_axes():
    """A far wall measured leaning by 10 degrees (Kinect depth bends far planes) and seen next to a doorway:
    its own tilted plane holds all its points, the vertical one about 60 %, and little of the frame is seen
    beyond it. As part of the room's shell it still takes the room's axes; the same slab with something
    behind it keeps its own plane."""
    wall = _wall(4.5, x=(-1.5, 0.5), y=(-0.6, 0.6), tilt_deg=10.0)
    door = _wall(6.5, x=(0.9, 1.2), y=(-0.6, 0.6))
    pts = torch.from_numpy(np.concatenate([wall, door, _floor()]))
    state = torch.zeros(len(pts), dtype=torch.float64)
    box = _box([-0.5, 0.0, 4.5], [1.0, 0.6, 0.01], _rx(10.0))  # the free fit: the tilted plane exactly
    free = _ctx(pts, state).score(box)
    alignment = Alignment("manhattan", UP, ROOM_AXES)
    aligned = align_winner(free, _ctx(pts, state), alignment)
    assert aligned.kind == "manhattan"
    a2, r2 = aligned.box.half[0].numpy(), aligned.box.rotation[0].numpy()
    assert abs(r2[:, int(np.argmin(a2))] @ [0.0, 0.0, 1.0]) == pytest.approx(1.0)
    # it kept what the room's shell must keep, not what other boxes must
    assert 0.5 * free.gain <= aligned.gain < 0.8 * free.gain
    # with points beyond it (the same wall in front of a deeper room) it is furniture, not the shell
    behind = _wall(6.0, x=(-1.5, 0.5), y=(0.8, 1.4))
    pts = torch.cat([pts, torch.from_numpy(behind)])
    state = torch.zeros(len(pts), dtype=torch.float64)
    ctx = _ctx(pts, state)
    assert align_winner(ctx.score(box), ctx, alignment).kind != "manhattan"

"""The shape of a winner after selection (fitting/winner.py, fitting/refit.py, fitting/align.py): a slab is
turned to the tightest rectangle of its points, it may thicken into the faces that continue past its edges,
re-fitted slabs keep their points on a face, and a slab that cannot be aligned stands with upright edges in
its own plane."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
import torch

from cuboidcli.fitting.align import Alignment, edge_to_vertical
from cuboidcli.fitting.box import Box, StepContext, values_one
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.refit import refit_box
from cuboidcli.fitting.scoring import ScoreParams
from cuboidcli.fitting.winner import grow_cuboid, square_slab
from cuboidcli.synth import render_boxes
from tests.conftest import simple_room

CFG = FitConfig()
SP = ScoreParams(CFG.tau_sq_m2, CFG.beta, CFG.tau_c, True)


def _yaw_z(deg: float) -> np.ndarray:
    """Rotation about the camera's z axis (in the image plane)."""
    t = np.deg2rad(deg)
    return np.array([[np.cos(t), -np.sin(t), 0.0], [np.sin(t), np.cos(t), 0.0], [0.0, 0.0, 1.0]])


def _t(*arrays):
    return tuple(torch.from_numpy(np.asarray(x, dtype=np.float64))[None] for x in arrays)


def _box(*arrays) -> Box:
    return Box(*_t(*arrays))


def _ctx(pts, state, config: FitConfig = CFG) -> StepContext:
    return StepContext.of(pts, state, config, SP)


@pytest.fixture(scope="module")
def cabinet_points(nyu_camera):
    """Grid points of :func:`conftest.simple_room` (the cabinet: centre (1.2, 0.9, 3.9), half-sizes
    (0.4, 0.5, 0.3), axis-aligned; its front face at z = 3.6, its top at y = 0.4) and the state of a set
    that holds the floor and the two walls."""
    room = simple_room()
    depth, _ = render_boxes(room, nyu_camera)
    pts = torch.from_numpy(nyu_camera.backproject(depth, 8).reshape(-1, 3)).double()
    pts = pts[pts[:, 2] > 0]
    state = torch.zeros(len(pts), dtype=torch.float64)
    from cuboidcli.geometry.kernels import combine

    for c in room[:3]:
        state = combine(values_one(pts, *_t(c.center, c.half_size, c.rotation), SP), state)
    return pts, state


def test_a_slab_at_a_random_in_plane_angle_is_turned_to_the_tightest_rectangle(cabinet_points):
    pts, state = cabinet_points
    ctx = _ctx(pts, state)
    # the cabinet's front as a thin slab on the face plane, turned 30 degrees in it (as six points leave it)
    out = square_slab(ctx.score(_box([1.2, 0.9, 3.6], [0.45, 0.45, 0.005], _yaw_z(30.0))), ctx)
    assert out is not None
    c2, a2, r2 = out.numpy()
    # its in-plane axes are the cabinet's edges again (x and y, up to sign and order), the normal kept
    assert abs(r2[:, 2] @ [0, 0, 1.0]) == pytest.approx(1.0, abs=1e-9)
    assert max(abs(r2[0, 0]), abs(r2[1, 0])) > np.cos(np.deg2rad(2.5))
    # and its points lie on its front face, which sits on the cabinet's front
    assert c2[2] - a2[2] == pytest.approx(3.6, abs=0.01)
    # a slab already on the edges is left as it is
    assert square_slab(ctx.score(_box([1.2, 0.9, 3.6], [0.4, 0.5, 0.005], np.eye(3))), ctx) is None


def test_a_front_slab_thickens_into_the_top_face(cabinet_points):
    pts, state = cabinet_points
    ctx = _ctx(pts, state)
    front = ctx.score(_box([1.2, 0.9, 3.6], [0.4, 0.5, 0.005], np.eye(3)))
    thick = grow_cuboid(front, ctx)
    thin = grow_cuboid(front, _ctx(pts, state, replace(CFG, grow_thickness=False)))
    assert thin.box.half[0, 2] == pytest.approx(0.005) and thin.gain == pytest.approx(front.gain, abs=1.0)
    # the top face (seen from above) is won too: the box reaches back over the cabinet's depth
    assert thick.gain > front.gain + 10.0
    assert 0.2 < float(thick.box.half[0, 2]) < 0.5
    assert torch.equal(front.box.half, _box([1.2, 0.9, 3.6], [0.4, 0.5, 0.005], np.eye(3)).half)  # input kept


def test_refitted_slab_keeps_its_points_on_a_face():
    rng = np.random.default_rng(0)
    # points of a wall at z = 3 (the slab's thickness axis is z), seen from the camera at the origin
    p = np.c_[rng.uniform(-1, 1, 500), rng.uniform(-0.8, 0.8, 500), np.full(500, 3.0)]
    for side in (1.0, -1.0):
        half = np.array([1.0, 0.8, 0.05])
        center = np.array([0.0, 0.0, 3.0 - side * 0.05])  # the points on the +z or -z face
        cn, an = refit_box(p, center, half, np.eye(3), 1e-3)
        face = cn[2] + side * an[2]
        assert face == pytest.approx(3.0, abs=1e-6), side
        assert an[2] == pytest.approx(0.05)
        assert an[0] == pytest.approx(0.98, abs=0.03) and an[1] == pytest.approx(0.78, abs=0.03)


def test_edge_to_vertical_turns_a_tilted_slab_in_its_plane():
    up = np.array([0.0, -1.0, 0.0])  # OpenCV: y down
    # a wall leaning back by 10 degrees, turned 25 degrees in its plane
    lean = np.array([[1, 0, 0], [0, np.cos(0.1745), -np.sin(0.1745)], [0, np.sin(0.1745), np.cos(0.1745)]])
    rot = lean @ _yaw_z(25.0)
    out = edge_to_vertical(rot, 2, Alignment("gravity", up))
    assert out is not None
    assert np.allclose(out[:, 2], rot[:, 2])  # the plane is kept
    assert np.linalg.det(out) == pytest.approx(1.0)
    # one in-plane axis is the steepest direction in the plane: it lies in span(up, normal)
    steep = [k for k in (0, 1) if abs(out[:, k] @ up) > 0.9]
    assert len(steep) == 1
    assert abs(out[:, steep[0]] @ np.cross(up, out[:, 2])) < 1e-9
    # a level slab without a room frame has no direction to turn to
    assert edge_to_vertical(np.eye(3)[:, [0, 2, 1]] * [1, 1, -1], 2, Alignment("gravity", up)) is None
    assert edge_to_vertical(rot, -1, Alignment("gravity", up)) is None


def test_the_refinement_runs_with_the_configured_settings(cabinet_points):
    """``refine_iters`` and ``refine_lr`` reach the backend's refinement; ``refine_keep`` decides whether the
    refined box replaces the selected one (a negative share: never)."""
    from cuboidcli.fitting.backend import NumbaBackend
    from cuboidcli.fitting.winner import refine_winner

    pts, state = cabinet_points
    seen = []

    class Spy(NumbaBackend):
        def refine(self, points, center, half, rotation, a_min, a_max, iters=0, lr=0.0):
            seen.append((iters, lr))
            return super().refine(points, center, half, rotation, a_min, a_max, iters, lr)

    config = replace(CFG, grow_rounds=0, refine_iters=7, refine_lr=0.01)
    ctx = StepContext.of(pts, state, config, SP, Spy())
    front = ctx.score(_box([1.2, 0.9, 3.6], [0.4, 0.5, 0.02], np.eye(3)))
    refine_winner(front, ctx)
    assert seen == [(7, 0.01)]
    never = StepContext.of(pts, state, replace(config, refine_keep=-1.0), SP, Spy())
    assert refine_winner(front, never) is front

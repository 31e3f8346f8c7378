"""Localised proposals, adaptive termination and growing of the winner, inside the estimator."""

import json
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest
import torch

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.presets import resolve
from cuboidcli.factories import make_solver
from cuboidcli.fitting.box import Box, Scored, StepContext
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.prepare import prepare_points
from cuboidcli.fitting.scoring import ScoreParams, gains_torch, values_torch
from cuboidcli.fitting.search import gain_upper_bound, miss_probability
from cuboidcli.fitting.winner import grow_cuboid
from cuboidcli.io.depth import read_depth
from cuboidcli.sampling import SequentialSampler
from cuboidcli.synth import render_boxes
from tests.conftest import fit_named

SAMPLE = Path(__file__).resolve().parents[2] / "cuboidcli" / "data" / "sample"


@pytest.fixture(scope="module")
def demo_room():
    cam = json.loads((SAMPLE / "camera.json").read_text())
    camera = Camera(cam["fx"], cam["fy"], cam["cx"], cam["cy"], cam["width"], cam["height"])
    return read_depth(SAMPLE / "sample_depth.png", cam["depth_scale"]), camera


def test_gain_upper_bound_is_exact_and_bounds_every_hypothesis():
    state = torch.tensor([0.0, 0.25, 1.0, -2.0, 0.9], dtype=torch.float64)
    assert gain_upper_bound(state) == pytest.approx(1.0 + 0.75 + 0.0 + 0.0 + 0.1)
    # no cuboid gains more than the bound, one that explains the open points reaches most of it
    g = torch.Generator().manual_seed(0)
    pts = torch.rand(200, 3, generator=g, dtype=torch.float64) + torch.tensor([0.0, 0.0, 2.0])
    st = torch.rand(200, generator=g, dtype=torch.float64) * 1.5 - 0.4
    centers = torch.rand(64, 3, generator=g, dtype=torch.float64) + torch.tensor([0.0, 0.0, 2.0])
    half = torch.rand(64, 3, generator=g, dtype=torch.float64) * 0.5 + 0.05
    rot = torch.eye(3, dtype=torch.float64).expand(64, 3, 3)
    gains = gains_torch(pts, centers, half, rot, st, ScoreParams(0.004, 5.0, 0.008))
    assert float(gains.max()) <= gain_upper_bound(st) + 1e-9


def test_miss_probability_falls_with_batches_and_needs_local_sets():
    n = 4800
    p = torch.full((1, n), 1.0 / n, dtype=torch.float64)
    q = torch.ones(1, dtype=torch.float64)
    state = torch.zeros(n, dtype=torch.float64)
    config = FitConfig(hypotheses=1024)
    one = miss_probability((p, q), state, 76.3, config, 0.75, 1)
    two = miss_probability((p, q), state, 76.3, config, 0.75, 2)
    assert 0.0 < two < one < 1.0
    assert two == pytest.approx(one**2)
    # global sets alone would need ~1e10 hypotheses to hit a 76-point structure: no confidence is gained
    assert miss_probability((p, q), state, 76.3, config, 0.0, 4) > 0.99
    # fewer open points than Theta: nothing left to miss
    state[: n - 50] = 1.0
    assert miss_probability((p, q), state, 76.3, config, 0.75, 1) == 0.0


def _wall(nyu_camera):
    """A frontal wall 2.4 x 1.6 m at 2.5 m (its edges inside the image), seen by the NYU camera."""
    wall = Cuboid(np.array([0.2, 0.1, 2.525]), np.array([1.2, 0.8, 0.025]), np.eye(3))
    depth, _ = render_boxes([wall], nyu_camera)
    return wall, depth


def test_grow_cuboid_pushes_faces_to_where_the_surface_ends(nyu_camera):
    wall, depth = _wall(nyu_camera)
    prep = prepare_points(depth, nyu_camera, 8).as_tensors()
    pts = prep.points.double()
    state = torch.zeros(pts.shape[0], dtype=torch.float64)
    sp = ScoreParams(0.004, 5.0, 0.008)
    config = FitConfig()
    # a patch of the wall: 0.4 x 0.3 m around its centre, thickness kept
    c = torch.tensor([[0.2, 0.1, 2.525]], dtype=torch.float64)
    a = torch.tensor([[0.2, 0.15, 0.025]], dtype=torch.float64)
    R = torch.eye(3, dtype=torch.float64)[None]
    g0 = float(gains_torch(pts, c, a, R, state, sp)[0])
    ctx = StepContext.of(pts, state, config, sp)
    patch = Box(c, a, R)
    grown = grow_cuboid(Scored(patch, ctx.values(patch), g0), ctx)
    c2, a2, values, g2 = grown.box.center, grown.box.half, grown.values, grown.gain
    assert g2 > 4 * g0
    assert float(a2[0, 2]) == pytest.approx(0.025)  # the slab stays thin
    lo, hi = (c2 - a2)[0], (c2 + a2)[0]
    true_lo = torch.tensor(wall.center - wall.half_size)
    true_hi = torch.tensor(wall.center + wall.half_size)
    # x and y faces end within one step of the wall's edges (never more than a step beyond them)
    assert ((lo[:2] - true_lo[:2]).abs() <= config.grow_step_m + 0.02).all(), (lo, true_lo)
    assert ((hi[:2] - true_hi[:2]).abs() <= config.grow_step_m + 0.02).all(), (hi, true_hi)
    assert torch.allclose(values, values_torch(pts, c2, a2, R, sp)[0])
    # no rounds: the gain and box stay
    still = grow_cuboid(grown, StepContext.of(pts, state, replace(config, grow_rounds=0), sp))
    assert still.gain == g2 and torch.equal(still.box.half, a2)


def test_growing_lets_one_cuboid_explain_a_whole_wall(nyu_camera):
    _, depth = _wall(nyu_camera)
    base = FitConfig(max_cuboids=1, hypotheses=256, local_fraction=1.0, local_radii_m=(0.3,), seed=1)
    _, plain = fit_named(depth, nyu_camera, replace(base, grow_rounds=0), sampler=SequentialSampler())
    _, grown = fit_named(depth, nyu_camera, base, sampler=SequentialSampler())
    wall_points = int((depth[::8, ::8] > 0).sum())
    assert plain.gains[0] < 0.7 * wall_points
    assert grown.gains[0] > 0.9 * wall_points


def test_demo_room_gives_its_cuboids_for_every_seed_at_1024_hypotheses(demo_room):
    depth, camera = demo_room
    config = FitConfig(hypotheses=1024, sampler="sequential")
    solver = make_solver(config)
    for seed in range(4):
        cuboids, info = fit_named(depth, camera, replace(config, seed=seed), solver=solver)
        assert len(cuboids) >= 4, (seed, info.gains, info.batches)
        assert len(info.batches) == info.iterations
        assert all(1 <= b <= config.max_batches for b in info.batches[: len(cuboids)])


def test_adaptive_termination_draws_more_batches_before_giving_up(demo_room):
    depth, camera = demo_room
    # a Theta no cuboid of the room reaches (its floor gains about 800) but a structure of that size
    # could exist and be missed: the step draws every batch allowed before giving up, and reports them
    config = FitConfig(hypotheses=256, sampler="sequential", theta=2000.0, max_batches=3, confidence=1 - 1e-9)
    cuboids, info = fit_named(depth, camera, config)
    assert cuboids == [] and info.batches == [3] and info.stop_reason == "gain_below_theta"
    assert 300 < info.rejected_gain < 2000
    # with a loose confidence one batch is enough to conclude
    _, info = fit_named(depth, camera, replace(config, confidence=0.5))
    assert info.batches == [1]
    # a Theta above what the points could ever give: stop without drawing anything
    cuboids, info = fit_named(depth, camera, replace(config, theta=1e9))
    assert info.batches == [0] and info.rejected_gain is None


def test_paper_preset_keeps_the_papers_sampling():
    config, _, _ = resolve("paper")
    assert (config.local_fraction, config.max_batches, config.refine) == (0.0, 1, False)
    assert config.slab_max_m is None and config.align == "free"  # every half-size within a_max
    for name in ("seqransac", "seqransac-oai", "ours"):
        config, _, _ = resolve(name)
        assert config.local_fraction == 0.0 and config.max_batches == 1 and config.slab_max_m is None

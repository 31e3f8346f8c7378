"""A hypothesis that collapsed to a line is not scored: the step picks the best box instead; a winner that
refining would make a line stays as it was drawn."""

from types import SimpleNamespace

import numpy as np
import pytest
import torch

from cuboidcli.fitting.backend import backend_for
from cuboidcli.fitting.box import not_lines
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.scoring import ScoreParams
from cuboidcli.fitting.search import search_step
from cuboidcli.sampling import SamplingContext, UniformSampler


def test_not_lines_keeps_boxes_and_plates_and_drops_lines():
    half = np.array(
        [
            [2.0, 0.001, 0.001],  # the solver's lower bound on two sides: a line
            [0.3, 0.006, 0.002],  # both under a tenth of tau (6.3 mm): a line
            [0.3, 0.0065, 0.001],  # a plate 13 mm wide: kept
            [1.0, 0.8, 0.001],  # a plate: kept
            [0.2, 0.3, 0.4],  # a box: kept
        ]
    )
    expected = [False, False, True, True, True]
    assert not_lines(half, 0.004).tolist() == expected
    assert not_lines(torch.from_numpy(half[:, ::-1].copy()), 0.004).tolist() == expected
    # outdoors (tau 0.2 m, half-sizes from 2 m) nothing is a line
    assert not_lines(np.array([[2.0, 2.0, 2.0], [30.0, 2.0, 2.0]]), 0.04).tolist() == [True, True]


class _Solver:
    """Every minimal set becomes one of two hypotheses, alternately: a 2 m line along x through the row of
    points, and a box whose face toward the camera holds a patch of points."""

    def __call__(self, sets):
        h = sets.shape[0]
        line = (torch.tensor([0.0, 0.0, 2.0]), torch.tensor([1.0, 0.001, 0.001]))
        box = (torch.tensor([0.0, 1.0, 2.0]), torch.tensor([0.1, 0.1, 0.1]))
        centers = torch.stack([line[0] if k % 2 == 0 else box[0] for k in range(h)]).double()
        half = torch.stack([line[1] if k % 2 == 0 else box[1] for k in range(h)]).double()
        return centers, half, torch.eye(3, dtype=torch.float64).expand(h, 3, 3).clone()


def _step(solver, hypotheses=8):
    g = torch.Generator().manual_seed(0)
    row = torch.stack([torch.linspace(-1, 1, 400), torch.zeros(400), torch.full((400,), 2.0)], 1)
    patch = (torch.rand(60, 3, generator=g) - 0.5) * torch.tensor([0.2, 0.2, 0.0])
    pts = torch.cat([row, patch + torch.tensor([0.0, 1.0, 1.9])]).double()
    ctx = SamplingContext(pts, torch.zeros(len(pts), dtype=torch.long), (1, len(pts)), torch.zeros(1, 1),
                          torch.zeros(len(pts), dtype=torch.float64), 0)  # fmt: skip
    config = FitConfig(hypotheses=hypotheses, local_fraction=0.0, max_batches=2)
    timing = {"sample": 0.0, "solve": 0.0, "score": 0.0}
    return search_step(
        ctx, UniformSampler(), solver, ctx.state, ScoreParams(), config, g, 1e9, timing, None,
        backend_for("torch", "cpu"),
    )  # fmt: skip


def test_the_step_picks_the_box_over_a_line_that_explains_more_points():
    gain, best, batches = _step(_Solver())
    assert batches == 1  # fewer open points than Theta: nothing more to find
    assert best is not None
    assert best.half[0].tolist() == pytest.approx([0.1, 0.1, 0.1])
    assert best.center[0].tolist() == pytest.approx([0.0, 1.0, 2.0])
    # the box explains the patch's 60 points (and none of the row), the line would have had the row's 400
    assert 40.0 < gain < 61.0


def test_a_batch_of_lines_only_gives_no_hypothesis():
    class Lines(_Solver):
        def __call__(self, sets):
            c, a, r = super().__call__(sets)
            return c[::2].repeat(2, 1)[: len(c)], a[::2].repeat(2, 1)[: len(c)], r

    gain, best, batches = _step(Lines())
    assert (gain, best, batches) == (-np.inf, None, 1)


def test_a_winner_refined_into_a_line_stays_as_drawn(monkeypatch):
    from cuboidcli.fitting import winner as W
    from cuboidcli.fitting.box import Box, Scored

    def scored(half):
        box = Box(torch.zeros(1, 3), torch.tensor([half]), torch.eye(3)[None])
        return Scored(box, torch.zeros(5), 10.0)

    drawn = scored([1.0, 0.2, 0.05])
    ctx = SimpleNamespace(config=SimpleNamespace(grow_rounds=0), sp=ScoreParams())
    monkeypatch.setattr(W, "_refine_once", lambda s, c: scored([2.0, 0.004, 0.001]))
    assert W.refine_winner(drawn, ctx) is drawn
    plate = scored([2.0, 0.3, 0.001])
    monkeypatch.setattr(W, "_refine_once", lambda s, c: plate)
    assert W.refine_winner(drawn, ctx) is plate


def test_a_winner_aligned_into_a_line_stays_as_it_was(room_depth, nyu_camera, monkeypatch):
    from dataclasses import replace

    from cuboidcli.fitting import pipeline
    from cuboidcli.fitting.box import Box
    from tests.conftest import fit_named

    def to_line(scored, ctx, alignment):
        c, a, r = scored.box.numpy()
        line = Box.from_numpy(c, np.array([a.max(), 0.001, 0.001]), r, like=scored.box.center)
        return replace(scored, box=line, kind="manhattan")

    monkeypatch.setattr(pipeline, "align_winner", to_line)
    cuboids, info = fit_named(room_depth[0], nyu_camera, FitConfig(seed=0, hypotheses=256, max_cuboids=3))
    assert len(cuboids) == 3
    assert all(np.sort(c.half_size)[1] > 0.05 for c in cuboids)
    assert info.aligned == ["free"] * 3

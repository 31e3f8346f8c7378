"""Hypothesis selection (fitting/backend.py select_best): what each path returns, beyond the winner."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest
import torch

from cuboidcli.fitting.backend import NumbaBackend
from cuboidcli.fitting.scoring import ScoreParams, gains_torch
from tests.geometry.test_fused import BETA, TAU, scene

SP = ScoreParams(TAU, BETA, 2 * TAU)


def test_gains_of_no_hypotheses_are_an_empty_vector():
    pts, c, a, R, state = scene(n=50, h=4)
    g = gains_torch(pts, c[:0], a[:0], R[:0], state, SP)
    assert g.shape == (0,) and g.dtype == torch.float64


def test_chunks_do_not_change_the_gains():
    pts, c, a, R, state = scene(n=300, h=70)
    whole = gains_torch(pts, c, a, R, state, SP, chunk=1000)
    torch.testing.assert_close(gains_torch(pts, c, a, R, state, SP, chunk=3), whole)
    torch.testing.assert_close(gains_torch(pts, c, a, R, state, SP), whole)


@pytest.mark.parametrize("prescore_points", [1, 300])
def test_fast_path_rescores_exactly_the_top_hypotheses(prescore_points):
    """The approximate path scores rescore_top hypotheses (64 by default) on all points, -inf the rest;
    every reported gain is exact."""
    pts, c, a, R, state = scene(seed=5)
    ref = gains_torch(pts, c, a, R, state, SP).numpy()
    gen = torch.Generator().manual_seed(0)
    best, gain, g = NumbaBackend().select_best(pts, c, a, R, state, SP, gen, prescore_points=prescore_points)
    finite = np.isfinite(g.numpy())
    assert finite.sum() == 64
    np.testing.assert_allclose(g.numpy()[finite], ref[finite], rtol=1e-9, atol=1e-9)
    assert gain == g[best] == g.numpy()[finite].max()


def test_exact_path_reports_every_gain_that_can_win():
    pts, c, a, R, state = scene(seed=6)
    ref = gains_torch(pts, c, a, R, state, SP).numpy()
    best, gain, g = NumbaBackend().select_best(pts, c, a, R, state, SP, torch.Generator().manual_seed(1))
    assert best == ref.argmax() and gain == pytest.approx(ref.max(), rel=1e-12)
    g = g.numpy()
    kept = np.isfinite(g)
    np.testing.assert_allclose(g[kept], ref[kept], rtol=1e-9, atol=1e-9)
    assert (ref[~kept] < ref.max()).all()


def test_score_params_are_frozen():
    with pytest.raises(dataclasses.FrozenInstanceError):
        SP.tau = 1.0  # type: ignore[misc]

"""Scoring hypotheses against a room (cuboidcli.geometry.room.room_gains and the room backend's exact
selection) against brute force: each gain is the sum over the points of the combined value minus the old
one, for every visibility; pruning abandons only hypotheses that stay below its threshold; the pruned,
chunked nomination selects what scoring every hypothesis on every point selects."""

from __future__ import annotations

import numpy as np
import pytest
import torch

import cuboidcli.fitting.room_backend as room_backend
from cuboidcli.fitting.room_backend import RoomBackend
from cuboidcli.fitting.scoring import ScoreParams
from cuboidcli.geometry.room import VISIBILITY, RoomPoints, room_gains, room_params, room_values
from cuboidcli.geometry.rotations import axis_angle_to_matrix

SP = ScoreParams(tau=0.02, beta=5.0, tau_c=0.04)


def scene(seed: int = 0, n: int = 6000):
    """A 5 x 4 x 2.5 m room's floor and two walls, a box standing in it, noise; viewpoints near the middle."""
    rng = np.random.default_rng(seed)
    k = n // 4
    floor = np.c_[rng.uniform(0, 5, k), rng.uniform(0, 4, k), np.zeros(k)]
    wall_x = np.c_[np.zeros(k), rng.uniform(0, 4, k), rng.uniform(0, 2.5, k)]
    wall_y = np.c_[rng.uniform(0, 5, k), np.zeros(k), rng.uniform(0, 2.5, k)]
    u = rng.uniform(-1, 1, (n - 3 * k, 3))
    face = rng.integers(0, 3, len(u))
    u[np.arange(len(u)), face] = np.sign(u[np.arange(len(u)), face])
    box = np.array([3.0, 2.0, 0.4]) + u * [0.5, 0.4, 0.4]
    points = np.concatenate([floor, wall_x, wall_y, box]) + rng.normal(0, 0.005, (n, 3))
    views = np.array([2.5, 2.0, 1.4]) + rng.normal(0, 0.3, (n, 3))
    return points, views


def hypotheses(h: int, seed: int = 1):
    rng = np.random.default_rng(seed)
    centers = rng.uniform([0, 0, 0], [5, 4, 2.5], (h, 3))
    centers[: h // 4] = np.array([3.0, 2.0, 0.4]) + rng.normal(0, 0.05, (h // 4, 3))  # near the box
    half = rng.uniform(0.05, 1.2, (h, 3))
    rot = axis_angle_to_matrix(torch.from_numpy(rng.normal(0, 0.3, (h, 3)))).numpy()
    return centers, half, rot


def brute_gains(room: RoomPoints, state: np.ndarray, centers, half, rot, params) -> np.ndarray:
    v = room_values(room, centers, half, rot, params)
    combined = np.where(np.minimum(v, state) < 0, np.minimum(v, state), np.maximum(v, state))
    return (combined - state).sum(axis=1)


def a_state(room: RoomPoints, params, seed: int = 2) -> np.ndarray:
    """The values of two cuboids already selected (a wall and part of the floor), combined."""
    c = np.array([[0.0, 2.0, 1.25], [2.5, 2.0, 0.0]])
    a = np.array([[0.01, 2.0, 1.25], [1.5, 2.0, 0.01]])
    v = room_values(room, c, a, np.stack([np.eye(3)] * 2), params)
    state = np.zeros(room.points.shape[0])
    for row in v:
        state = np.where(np.minimum(row, state) < 0, np.minimum(row, state), np.maximum(row, state))
    return state


@pytest.mark.parametrize("visibility", VISIBILITY)
def test_gains_are_the_sum_of_combined_values(visibility):
    points, views = scene()
    room = RoomPoints.build(points, views, visibility)
    params = room_params(SP.tau, SP.beta, SP.tau_c)
    state = a_state(room, params)
    c, a, R = hypotheses(300)
    exact = brute_gains(room, state, c, a, R, params)
    got = room_gains(room, state, c, a, R, params)
    assert np.allclose(got, exact, rtol=1e-10, atol=1e-8)
    assert exact.max() > 25 and len(np.unique(np.round(exact, 6))) > 200
    # pruning at the 90th percentile: those kept are exact, those dropped stay below it
    threshold = float(np.percentile(exact, 90))
    pruned = room_gains(room, state, c, a, R, params, prune_below=threshold)
    kept = np.isfinite(pruned)
    assert np.allclose(pruned[kept], exact[kept], rtol=1e-10, atol=1e-8)
    assert (exact[~kept] < threshold).all() and (~kept).sum() > 150
    assert kept[exact >= threshold].all()


@pytest.mark.parametrize("chunk", [1, 7, 256, 10_000])
def test_the_pruned_nomination_selects_the_exact_best(monkeypatch, chunk):
    monkeypatch.setattr(room_backend, "NOMINATION_CHUNK", chunk)
    points, views = scene(3)
    room = RoomPoints.build(points, views, "views")
    params = room_params(SP.tau, SP.beta, SP.tau_c)
    state = a_state(room, params)
    c, a, R = hypotheses(400, seed=4)
    exact = brute_gains(room, state, c, a, R, params)
    backend = RoomBackend(room)
    calls = []

    def spy(r, st, centers, *args, **kwargs):
        prune = kwargs.get("prune_below", args[3] if len(args) > 3 else -np.inf)
        got = room_gains(r, st, centers, *args, **kwargs)
        calls.append((r.points.shape[0], np.array(centers), prune))
        results.append(got)
        return got

    results = []

    monkeypatch.setattr(room_backend, "room_gains", spy)
    best, gain, g = backend.select_best(
        torch.from_numpy(room.points), torch.from_numpy(c), torch.from_numpy(a), torch.from_numpy(R),
        torch.from_numpy(state), SP, torch.Generator().manual_seed(0),
    )  # fmt: skip
    assert best == int(np.argmax(exact)) and gain == pytest.approx(exact.max(), rel=1e-10)
    g = g.numpy()
    kept = np.isfinite(g)
    assert np.allclose(g[kept], exact[kept], rtol=1e-10, atol=1e-8)
    # the nominees, the 16 best on every 8th point of each block whatever the chunk, set the full pass's
    # threshold: the best of their exact gains
    keep, sub = room.subsample(room_backend.NOMINATION_STEP)
    sub_exact = brute_gains(sub, state[keep], c, a, R, params)
    nominees = np.argsort(-sub_exact, kind="stable")[: room_backend.NOMINATED]
    n_full, full_centers, threshold = calls[-1]  # the others: the nominees' exact gains are known
    others = np.setdiff1d(np.arange(400), nominees)
    assert n_full == len(points) and np.array_equal(full_centers, c[others])
    n_top, top_centers, _ = calls[-2]  # the nominees, scored on every point
    assert n_top == len(points) and np.array_equal(top_centers, c[nominees])
    assert threshold == pytest.approx(exact[nominees].max() - room_backend.PRUNE_MARGIN, rel=1e-10)
    assert (exact[~kept] < threshold).all() and (~kept).sum() > 100
    sub_calls = [call for call in calls if call[0] == len(sub.points)]
    assert sum(len(h) for _, h, _ in sub_calls) == 400 and len(sub_calls) == -(-400 // chunk)
    # the subset is scored in its own coarser blocks, each point with its own state: its gains are the
    # subset's, for every hypothesis the chunks' pruning kept
    nominated = np.concatenate(
        [g for call, g in zip(calls, results, strict=True) if call[0] == len(sub.points)]
    )
    scored = np.isfinite(nominated)
    assert scored.sum() >= room_backend.NOMINATED
    assert np.allclose(nominated[scored], sub_exact[scored], rtol=1e-10, atol=1e-8)
    assert len(backend._nom.start) < len(backend._sub.start)  # fewer, larger blocks

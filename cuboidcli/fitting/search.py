"""One step's search for its best hypothesis (paper Sec. 3.2, Fig. 3): batches of minimal sets are drawn
by the sampler, solved by the solver and scored by the backend until the best one gains Theta or adaptive
termination says nothing would (:func:`miss_probability`). Hypotheses that collapsed to a line
(:func:`~cuboidcli.fitting.box.not_lines`) are not scored."""

from __future__ import annotations

import time

import numpy as np

from cuboidcli.fitting.align import Alignment
from cuboidcli.fitting.backend import ScoringBackend, backend_for
from cuboidcli.fitting.box import Box, not_lines
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.scoring import ScoreParams
from cuboidcli.geometry.arrays import as_kind, cat, device_of, no_grad, numpy64
from cuboidcli.geometry.inlier import INLIER_CUT
from cuboidcli.sampling import Sampler, SamplingContext, draw_hypotheses, local_fraction_of
from cuboidcli.solvers.base import CuboidSolver, solve_upright


def solve_sets(solver: CuboidSolver, sets, config: FitConfig, alignment: Alignment | None):
    """Boxes for the minimal sets (H, C, 3): free, or under an alignment ``config.upright_fraction`` of
    them upright (yaw-only, from the first ``config.upright_set_size`` points of their sets; with
    "manhattan" half of those on the room's axes), the rest free. Returns (centers (H, 3), half_sizes
    (H, 3), rotations (H, 3, 3)), of the sets' kind."""
    n_up = 0 if alignment is None else int(round(config.upright_fraction * sets.shape[0]))
    if n_up == 0:
        return solver(sets)
    frame = alignment.frame()
    n_free = sets.shape[0] - n_up
    parts = [solver(sets[:n_free])] if n_free else []
    up = sets[:, : max(1, min(config.upright_set_size, sets.shape[1]))]
    if alignment.axes is not None:
        n_fixed = n_up // 2
        parts.append(solve_upright(solver, up[n_free : n_free + n_fixed], frame, fixed=True))
        parts.append(solve_upright(solver, up[n_free + n_fixed :], frame))
    else:
        parts.append(solve_upright(solver, up[n_free:], frame))
    return tuple(cat([p[k] for p in parts if p[k].shape[0]]) for k in range(3))


def search_step(
    ctx: SamplingContext,
    sampler: Sampler,
    solver: CuboidSolver,
    state,
    sp: ScoreParams,
    config: FitConfig,
    gen,
    theta: float,
    timing: dict,
    alignment: Alignment | None = None,
    backend: ScoringBackend | None = None,
) -> tuple[float, Box | None, int]:
    """The best hypothesis of one step: batches of |H| minimal sets are drawn, solved and scored (by
    ``backend``; None = the default of the points' device) until the best gains Theta, the miss
    probability falls below 1 - confidence, or ``config.max_batches`` is reached. Returns (its gain, its
    box, the batches drawn); ``timing`` collects the seconds of "sample", "solve" and "score". The arrays
    are of one kind (numpy, or tensors), ``gen`` of theirs."""
    pts = ctx.points
    backend = backend or backend_for(config.backend, device_of(pts))
    local_frac = local_fraction_of(sampler, config.local_fraction)
    gain, best, batches = -np.inf, None, 0
    t = time.perf_counter()
    with no_grad(pts):
        dists = sampler.distributions(ctx)
    timing["sample"] += time.perf_counter() - t
    while True:
        t = time.perf_counter()
        with no_grad(pts):
            _, idx, _ = draw_hypotheses(
                sampler, ctx, config.hypotheses, config.min_set, gen, local_frac, config.local_radii_m, dists
            )
        idx = as_kind(idx, pts)
        t2 = time.perf_counter()
        timing["sample"] += t2 - t
        centers, half, rot = solve_sets(solver, pts[idx], config, alignment)
        keep = not_lines(half, sp.tau)
        if not keep.all():
            centers, half, rot = (x[as_kind(np.flatnonzero(keep), pts)] for x in (centers, half, rot))
        t3 = time.perf_counter()
        timing["solve"] += t3 - t2
        b, g = -1, -np.inf
        if keep.any():
            b, g, _ = backend.select_best(
                pts, centers, half, rot, state, sp, gen, config.prescore_points, config.rescore_top
            )
        timing["score"] += time.perf_counter() - t3
        batches += 1
        if g > gain:
            gain, best = g, Box(centers[b : b + 1], half[b : b + 1], rot[b : b + 1])
        if gain > theta or batches >= config.max_batches:
            return gain, best, batches
        if miss_probability(dists, state, theta, config, local_frac, batches) <= 1.0 - config.confidence:
            return gain, best, batches


def gain_upper_bound(state) -> float:
    """The largest inlier-count gain any cuboid could add: a point with state s >= 0 gains at most 1 - s,
    an occluded point (s < 0) nothing (combine keeps the minimum of negative values)."""
    s = numpy64(state)
    return float((1.0 - np.minimum(s[s >= 0], 1.0)).sum())


def miss_probability(
    dists: tuple,
    state,
    theta: float,
    config: FitConfig,
    local_fraction: float,
    batches: int,
) -> float:
    """Probability that ``batches`` batches missed a structure that would gain Theta; ``dists`` = the
    sampler's (p (Q, N), q (Q,)) of the step.

    Such a structure holds at least Theta points that are not yet explained (state < ``INLIER_CUT``).
    Under the sampler's first-point distribution (the mixture sum_j q_j p_j) it is seeded with probability
    m = Theta * (mean weight of an unexplained point); a localised set seeded on it wins it with probability
    ``config.local_success``; global sets are counted as never winning it (their six points must all land
    on it: m^6). The miss probability of H hypotheses per batch is (1 - f m rho)^(H b).
    """
    p, q = numpy64(dists[0]), numpy64(dists[1])
    mix = (q[:, None] * p).sum(0)
    s = numpy64(state)
    open_ = (s < INLIER_CUT) & (s >= 0)
    n_open = int(open_.sum())
    if n_open < theta:
        return 0.0
    m = min(theta * float(mix[open_].sum()) / n_open, 1.0)
    hit = local_fraction * m * config.local_success + (1.0 - local_fraction) * m**config.min_set
    if hit <= 0.0:
        return 1.0
    return float(np.exp(config.hypotheses * batches * np.log1p(-min(hit, 1.0 - 1e-12))))

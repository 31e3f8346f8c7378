"""The estimator (paper Sec. 3.2, Fig. 3): sample minimal sets -> solve -> score -> select, one cuboid
per step, until the best hypothesis no longer raises the occlusion-aware inlier count by Theta.

Entry points: :func:`fit_depth` (a depth map and its camera) and :func:`fit_points` (prepared points).
Both take a built solver (:class:`~cuboidcli.solvers.base.CuboidSolver`) and sampler
(:class:`~cuboidcli.sampling.Sampler`) and return ``(cuboids, FitInfo)``; building them by name, with
their weights, is :mod:`cuboidcli.factories`' work.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np
import torch

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.assign import OCCLUDED, assign_points
from cuboidcli.fitting.backend import NumbaBackend, ScoreParams, ScoringBackend, backend_for
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.winner import Alignment, align_winner, cuboid_kind, refine_winner, values_one
from cuboidcli.geometry.fused import ImageCells
from cuboidcli.geometry.gravity import Gravity, estimate_gravity, given_gravity, manhattan_axes
from cuboidcli.geometry.kernels import combine
from cuboidcli.sampling import (
    Sampler,
    SamplingContext,
    draw_hypotheses,
    local_fraction_of,
)
from cuboidcli.sampling.space import SpaceCells
from cuboidcli.solvers.base import CuboidSolver, solve_upright

INVALID = -3

ProgressFn = Callable[[int, int, float], None]
"""progress(step, cuboids_so_far, last_gain) is called after every step."""


@dataclass
class FitInfo:
    """What happened while fitting one frame."""

    gains: list[float] = field(default_factory=list)
    """Inlier-count gain of each selected cuboid, in selection order."""
    theta: float = 0.0
    """Stopping threshold used: ``theta`` if given, else k ln n with k = ``theta_log_factor`` (6 by default;
    the paper's 9)."""
    n_points: int = 0
    """Valid fitting points n."""
    iterations: int = 0
    """Sampling steps run, including a final step whose best hypothesis was rejected."""
    batches: list[int] = field(default_factory=list)
    """Batches of |H| hypotheses drawn in each step (adaptive termination draws more when a step's best
    hypothesis misses Theta); 0 for a final step skipped because no hypothesis could gain Theta."""
    stop_reason: str = ""
    """max_cuboids | gain_below_theta | too_few_points."""
    rejected_gain: float | None = None
    """Gain of the best hypothesis of the rejecting step, if any."""
    timing_s: dict = field(default_factory=dict)
    """Per-stage seconds; 'total' is input loaded -> cuboids selected."""
    grid_step: int = 8
    """Step of the fitting grid used (``FitConfig.step_for`` the frame's size)."""
    assignment: np.ndarray | None = None
    """(Hs, Ws) int32 over the fitting grid: k >= 0 inlier of cuboid k, -1 none, -2 occluded, -3 no depth."""
    state: np.ndarray | None = None
    """(N,) f_OAI of the final set at the valid fitting points."""
    gravity: Gravity | None = None
    """The up/down direction used or estimated (None when not needed or not reliable)."""
    align: str = "free"
    """The orientation constraint applied: the configured one, or "free" when no gravity was available."""
    aligned: list[str] = field(default_factory=list)
    """Per selected cuboid: "manhattan", "gravity", "tilted" (a slab kept in its own, tilted plane with its
    edges turned upright) or "free" (an aligned box fitted much worse)."""
    warnings: list[str] = field(default_factory=list)
    """Things the user should know about this fit (one line each)."""

    def add_depth_time(self, seconds: float) -> None:
        """Count a depth estimation from RGB as part of the frame's fitting time: stage "depth" (first) and
        in "total" (the network is part of the pipeline; loading it is start-up and is not counted)."""
        self.timing_s = {"depth": round(seconds, 6), **self.timing_s}
        self.timing_s["total"] = round(self.timing_s.get("total", 0.0) + seconds, 6)


@dataclass
class PreparedPoints:
    points: torch.Tensor  # (N, 3) float32, metres
    grid_index: torch.Tensor  # (N,) flat index into the fitting grid
    grid_shape: tuple[int, int]
    depth_grid: torch.Tensor  # (Hs, Ws) metres, 0 = invalid
    focal_cells: tuple[float, float] | None = None  # (fx, fy) / grid_step: focal lengths in grid cells
    grid_step: int = 8
    cells: ImageCells | None = None  # the points binned by grid cell (scoring visits the cells it can reach)
    space: SpaceCells | None = None  # unorganised points (a room): the voxel cells localised sets search


def prepare_points(
    depth_m: np.ndarray, camera: Camera, grid_step: int, device: str = "cpu"
) -> PreparedPoints:
    """The fitting grid: every grid_step-th pixel (nearest, no averaging), invalid depth excluded."""
    if depth_m.shape != (camera.height, camera.width):
        raise ValueError(
            f"depth map is {depth_m.shape[1]}x{depth_m.shape[0]} but the camera is "
            f"{camera.width}x{camera.height}"
        )
    # Subsample before masking: on a 12 MP photo the full-size mask would cost more than the fit's grid.
    sub = depth_m[::grid_step, ::grid_step]
    grid = camera.backproject_grid(np.where(valid_depth(sub), sub, 0.0), grid_step)
    depth_grid = grid[..., 2]
    flat = grid.reshape(-1, 3)
    ok = np.flatnonzero(flat[:, 2] > 0)
    u, v = camera.pixel_grid(grid_step)
    cells = ImageCells.of_grid(ok, (u[0] - camera.cx) / camera.fx, (v[:, 0] - camera.cy) / camera.fy)
    return PreparedPoints(
        points=torch.from_numpy(flat[ok].astype(np.float32)).to(device),
        grid_index=torch.from_numpy(ok),
        grid_shape=depth_grid.shape,
        depth_grid=torch.from_numpy(depth_grid.astype(np.float32)).to(device),
        focal_cells=(camera.fx / grid_step, camera.fy / grid_step),
        grid_step=grid_step,
        cells=cells,
    )


_COMPILED = False


def ensure_compiled(solver: CuboidSolver | None = None) -> None:
    """Compile (or load from cache) the fused CPU kernels once per process, outside any timing: those of the
    numba backend (scoring, values, refinement) and the localised sampler's, and the ``solver``'s own when
    it has a ``warm_up`` method (the numerical solver does)."""
    global _COMPILED
    warm_up = getattr(solver, "warm_up", None)
    if warm_up is not None:
        warm_up()
    if _COMPILED:
        return
    NumbaBackend().warm_up()
    from cuboidcli.sampling.proposals import ball_minimal_sets

    ball_minimal_sets(
        torch.tensor([[0.0, 0.0, 2.0], [0.1, 0.0, 2.0]]),
        torch.tensor([0, 1]),
        (1, 2),
        torch.tensor([0]),
        6,
        torch.Generator().manual_seed(0),
        focal_cells=(60.0, 60.0),
    )
    _COMPILED = True


def fit_points(
    prep: PreparedPoints,
    config: FitConfig,
    solver: CuboidSolver,
    sampler: Sampler,
    progress: ProgressFn | None = None,
    timing: dict | None = None,
    alignment: Alignment | None = None,
    backend: ScoringBackend | None = None,
) -> tuple[list[Cuboid], FitInfo]:
    """Sequential robust fitting on prepared points (Sec. 3.2). ``timing`` collects per-stage seconds;
    ``alignment`` constrains the orientation of the selected cuboids (None = free). The scoring and
    refinement backend is chosen here, once, from ``config.backend`` and the points' device
    (ValueError for "numba" on a GPU), unless a ``backend`` is given (a room's, which knows how its
    points were seen)."""
    timing = {} if timing is None else timing
    for k in ("sample", "solve", "score", "update"):
        timing.setdefault(k, 0.0)
    pts = prep.points
    n = pts.shape[0]
    info = FitInfo(
        theta=config.theta_for(n),
        n_points=n,
        grid_step=prep.grid_step,
        align="free" if alignment is None else alignment.mode,
    )
    sp = ScoreParams(config.tau_sq_m2, config.beta, config.tau_c, config.occlusion_aware)
    backend = backend or backend_for(config.backend, pts.device)
    if prep.cells is not None:
        backend.bind_cells(pts, prep.cells)
    gen = torch.Generator().manual_seed(config.seed)
    state = torch.zeros(n, dtype=torch.float64, device=pts.device)
    cuboids: list[Cuboid] = []
    if n < config.min_set:
        info.stop_reason = "too_few_points"
        info.state = state.cpu().numpy()
        return cuboids, info
    while True:
        if len(cuboids) >= config.max_cuboids:
            info.stop_reason = "max_cuboids"
            break
        info.iterations += 1
        ctx = SamplingContext(
            pts,
            prep.grid_index,
            prep.grid_shape,
            prep.depth_grid,
            state.float(),
            len(cuboids),
            prep.focal_cells,
            prep.space,
        )
        if not gain_upper_bound(state) > info.theta:  # no hypothesis can gain Theta: stop without drawing
            info.stop_reason = "gain_below_theta"
            info.rejected_gain = None
            info.batches.append(0)
            break
        gain, best_hyp, batches = _search_step(
            ctx, sampler, solver, state, sp, config, gen, info.theta, timing, alignment, backend
        )
        info.batches.append(batches)
        t4 = time.perf_counter()
        if not gain > info.theta:
            info.stop_reason = "gain_below_theta"
            info.rejected_gain = gain
            break
        c_b, a_b, R_b = best_hyp
        values = values_one(pts, c_b, a_b, R_b, sp, backend)
        if config.refine:
            c_b, a_b, R_b, values, gain = refine_winner(
                pts, c_b, a_b, R_b, values, state, gain, sp, config, gen, backend
            )
            t5 = time.perf_counter()
            timing["refine"] = timing.get("refine", 0.0) + t5 - t4
            t4 = t5
        if alignment is not None:
            c_b, a_b, R_b, values, gain, kind = align_winner(
                pts, c_b, a_b, R_b, values, state, gain, sp, config, alignment, backend
            )
            info.aligned.append(kind)
            t5 = time.perf_counter()
            timing["align"] = timing.get("align", 0.0) + t5 - t4
            t4 = t5
        cuboids.append(
            Cuboid(c_b[0].cpu().numpy(), a_b[0].cpu().numpy(), R_b[0].cpu().numpy(), inlier_gain=gain)
        )
        info.gains.append(gain)
        state = combine(values, state)
        timing["update"] += time.perf_counter() - t4
        if progress is not None:
            progress(info.iterations, len(cuboids), gain)
    info.state = state.cpu().numpy()
    return cuboids, info


def _solve(solver, sets: torch.Tensor, config: FitConfig, alignment: Alignment | None):
    """Boxes for the minimal sets (H, C, 3): free, or under an alignment ``config.upright_fraction`` of
    them upright (yaw-only, from the first ``config.upright_set_size`` points of their sets; with
    "manhattan" half of those on the room's axes), the rest free."""
    n_up = 0 if alignment is None else int(round(config.upright_fraction * sets.shape[0]))
    if n_up == 0:
        return solver(sets)
    frame = torch.from_numpy(alignment.frame())
    n_free = sets.shape[0] - n_up
    parts = [solver(sets[:n_free])] if n_free else []
    up = sets[:, : max(1, min(config.upright_set_size, sets.shape[1]))]
    if alignment.axes is not None:
        n_fixed = n_up // 2
        parts.append(solve_upright(solver, up[n_free : n_free + n_fixed], frame, fixed=True))
        parts.append(solve_upright(solver, up[n_free + n_fixed :], frame))
    else:
        parts.append(solve_upright(solver, up[n_free:], frame))
    return tuple(torch.cat([p[k] for p in parts if p[k].shape[0]]) for k in range(3))


def _search_step(
    ctx,
    sampler,
    solver,
    state,
    sp: ScoreParams,
    config: FitConfig,
    gen,
    theta,
    timing,
    alignment=None,
    backend: ScoringBackend | None = None,
):
    """The best hypothesis of one step: batches of |H| minimal sets are drawn, solved and scored (by
    ``backend``; None = the default of the points' device) until the best gains Theta, the miss
    probability falls below 1 - confidence, or ``config.max_batches`` is reached. Returns (gain,
    (centers, half_sizes, rotations) of the best as (1, ...) tensors, batches)."""
    pts = ctx.points
    backend = backend or backend_for(config.backend, pts.device)
    local_frac = local_fraction_of(sampler, config.local_fraction)
    gain, best, batches = -np.inf, None, 0
    t = time.perf_counter()
    with torch.no_grad():
        dists = sampler.distributions(ctx)
    timing["sample"] += time.perf_counter() - t
    while True:
        t = time.perf_counter()
        with torch.no_grad():
            _, idx, _ = draw_hypotheses(
                sampler, ctx, config.hypotheses, config.min_set, gen, local_frac, config.local_radii_m, dists
            )
        idx = idx.to(pts.device)
        t2 = time.perf_counter()
        timing["sample"] += t2 - t
        centers, half, rot = _solve(solver, pts[idx], config, alignment)
        t3 = time.perf_counter()
        timing["solve"] += t3 - t2
        b, g, _ = backend.select_best(
            pts, centers, half, rot, state, sp, gen, config.prescore_points, config.rescore_top
        )
        timing["score"] += time.perf_counter() - t3
        batches += 1
        if g > gain:
            gain, best = g, (centers[b : b + 1], half[b : b + 1], rot[b : b + 1])
        if gain > theta or batches >= config.max_batches:
            return gain, best, batches
        if miss_probability(dists, state, theta, config, local_frac, batches) <= 1.0 - config.confidence:
            return gain, best, batches


def gain_upper_bound(state: torch.Tensor) -> float:
    """The largest inlier-count gain any cuboid could add: a point with state s >= 0 gains at most 1 - s,
    an occluded point (s < 0) nothing (combine keeps the minimum of negative values)."""
    s = state.double()
    return float((1.0 - s[s >= 0].clamp_max(1.0)).sum())


def miss_probability(
    dists: tuple[torch.Tensor, torch.Tensor],
    state: torch.Tensor,
    theta: float,
    config: FitConfig,
    local_fraction: float,
    batches: int,
) -> float:
    """Probability that ``batches`` batches missed a structure that would gain Theta; ``dists`` = the
    sampler's (p (Q, N), q (Q,)) of the step.

    Such a structure holds at least Theta points that are not yet explained (state < 0.5). Under the
    sampler's first-point distribution (the mixture sum_j q_j p_j) it is seeded with probability
    m = Theta * (mean weight of an unexplained point); a localised set seeded on it wins it with probability
    ``config.local_success``; global sets are counted as never winning it (their six points must all land
    on it: m^6). The miss probability of H hypotheses per batch is (1 - f m rho)^(H b).
    """
    p, q = dists
    mix = (q[:, None] * p).sum(0).cpu()
    open_ = (state.cpu() < 0.5) & (state.cpu() >= 0)
    n_open = int(open_.sum())
    if n_open < theta:
        return 0.0
    m = min(theta * float(mix[open_].sum()) / n_open, 1.0)
    hit = local_fraction * m * config.local_success + (1.0 - local_fraction) * m**config.min_set
    if hit <= 0.0:
        return 1.0
    return float(np.exp(config.hypotheses * batches * np.log1p(-min(hit, 1.0 - 1e-12))))


def fit_depth(
    depth_m: np.ndarray,
    camera: Camera,
    config: FitConfig | None = None,
    *,
    solver: CuboidSolver,
    sampler: Sampler,
    progress: ProgressFn | None = None,
) -> tuple[list[Cuboid], FitInfo]:
    """Fit cuboids to a depth map (H, W) in metres (0/NaN/inf = missing) seen by ``camera``, with a built
    ``solver`` and ``sampler`` (:mod:`cuboidcli.factories` builds them by name; :class:`cuboidcli.api.Fitter`
    does both).

    Returns the selected cuboids (in selection order, each with its ``inlier_gain``) and a FitInfo.
    Deterministic for a given ``config.seed``.
    """
    config = config or FitConfig()
    device = config.device
    if device == "cpu":
        ensure_compiled(solver)
    t0 = time.perf_counter()
    prep = prepare_points(depth_m, camera, config.step_for(*depth_m.shape), device)
    timing = {"prepare": time.perf_counter() - t0}
    t = time.perf_counter()
    gravity, alignment, warning = resolve_alignment(prep, config)
    if config.align != "free" or config.gravity_down is not None:
        timing["gravity"] = time.perf_counter() - t
    cuboids, info = fit_points(prep, config, solver, sampler, progress, timing, alignment)
    info.gravity = gravity
    # What each box is (floor, wall, ceiling, object); without gravity the camera's y axis stands for down.
    down = gravity.down if gravity is not None else np.array([0.0, 1.0, 0.0])
    points = prep.points.double().cpu().numpy()
    for c in cuboids:
        c.kind = cuboid_kind(points, c, np.asarray(down, dtype=np.float64))
    if warning:
        info.warnings.append(warning)
    timing["total"] = time.perf_counter() - t0
    t = time.perf_counter()
    info.assignment = grid_assignment(prep, info.state, cuboids, config)
    timing["assign"] = time.perf_counter() - t
    info.timing_s = {k: round(v, 6) for k, v in timing.items()}
    return cuboids, info


def resolve_alignment(
    prep: PreparedPoints, config: FitConfig
) -> tuple[Gravity | None, Alignment | None, str]:
    """Gravity and the orientation constraint of a fit: (gravity or None, alignment or None, warning).

    A given ``config.gravity_down`` is used as it is; otherwise gravity is estimated from the depth map
    when ``config.align`` needs it (geometry/gravity.py). "manhattan" also needs the room's horizontal
    axes, estimated from the surface normals and made exactly perpendicular to the gravity used. Without
    a reliable gravity the fit stays free, with a warning.
    """
    if config.align == "free" and config.gravity_down is None:
        return None, None, ""
    hs, ws = prep.grid_shape
    grid = np.zeros((hs * ws, 3))
    grid[prep.grid_index.numpy()] = prep.points.double().cpu().numpy()
    grid = grid.reshape(hs, ws, 3)
    estimated = estimate_gravity(grid, seed=config.seed)
    if config.gravity_down is not None:
        gravity = given_gravity(config.gravity_down)
        if estimated is not None:  # keep the room's axes for "manhattan", made vertical for the given down
            gravity = Gravity(
                gravity.down, "given", 1.0, manhattan_axes(gravity.down, estimated.frame), estimated.support
            )
    else:
        gravity = estimated
    if config.align == "free":
        return gravity, None, ""
    if gravity is None:
        return (
            None,
            None,
            (
                f"no reliable gravity in this depth map (too few floor, wall or table surfaces); "
                f"cuboids are fitted free instead of {config.align}-aligned (give --gravity gx,gy,gz)"
            ),
        )
    axes = gravity.frame if config.align == "manhattan" else None
    warning = ""
    if config.align == "manhattan" and axes is None:
        warning = "no room axes in this depth map; cuboids are gravity-aligned with a free yaw"
    return gravity, Alignment(config.align, gravity.up, axes), warning


def grid_assignment(
    prep: PreparedPoints, state: np.ndarray, cuboids: list[Cuboid], config: FitConfig
) -> np.ndarray:
    """Per fitting-grid cell label (Hs, Ws): cuboid index, -1 none, -2 occluded, -3 no depth; the values
    come from the fit's backend (``config.backend`` on the points' device)."""
    labels = np.full(prep.grid_shape[0] * prep.grid_shape[1], INVALID, dtype=np.int32)
    lab = assign_points(
        prep.points,
        cuboids,
        config.tau_sq_m2,
        config.beta,
        config.tau_c,
        config.occlusion_aware,
        backend_for(config.backend, prep.points.device),
    )
    if state is not None and len(cuboids):
        lab[state < 0] = OCCLUDED
    labels[prep.grid_index.numpy()] = lab
    return labels.reshape(prep.grid_shape)

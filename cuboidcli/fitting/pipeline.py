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

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.align import Alignment, align_winner
from cuboidcli.fitting.backend import NumbaBackend, ScoringBackend, backend_for
from cuboidcli.fitting.box import Scored, StepContext, score_params
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.prepare import PreparedPoints, grid_assignment, prepare_points, resolve_alignment
from cuboidcli.fitting.search import gain_upper_bound, search_step
from cuboidcli.fitting.shell import cuboid_kind
from cuboidcli.fitting.winner import refine_winner
from cuboidcli.geometry.gravity import Gravity
from cuboidcli.geometry.kernels import combine
from cuboidcli.sampling import Sampler, SamplingContext
from cuboidcli.solvers.base import CuboidSolver

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


_COMPILED = False


def warm_up_parts(*parts) -> None:
    """Let each given part (a solver, a sampler) compile its own kernels: ``part.warm_up()``. A part
    without the method, or None, has nothing to compile."""
    for part in parts:
        warm_up = getattr(part, "warm_up", None)
        if warm_up is not None:
            warm_up()


def ensure_compiled(solver: CuboidSolver | None = None, sampler: Sampler | None = None) -> None:
    """Compile (or load from numba's cache) the fused CPU kernels of a fit once per process, outside any
    timing: the numba backend's (scoring, values, refinement) and the given parts' own
    (:func:`warm_up_parts`: the numerical solver's loops, the localised minimal sets of a sampler)."""
    global _COMPILED
    warm_up_parts(solver, sampler)
    if _COMPILED:
        return
    NumbaBackend().warm_up()
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
    sp = score_params(config)
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
        sampling = SamplingContext(
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
        gain, best, batches = search_step(
            sampling, sampler, solver, state, sp, config, gen, info.theta, timing, alignment, backend
        )
        info.batches.append(batches)
        t4 = time.perf_counter()
        if not gain > info.theta:
            info.stop_reason = "gain_below_theta"
            info.rejected_gain = gain
            break
        step = StepContext(pts, state, sp, config, backend, gen)
        # the search's gain stands: the backend's scoring loop computed it exactly
        winner = Scored(best, step.values(best), gain)
        if config.refine:
            winner = refine_winner(winner, step)
            t5 = time.perf_counter()
            timing["refine"] = timing.get("refine", 0.0) + t5 - t4
            t4 = t5
        if alignment is not None:
            winner = align_winner(winner, step, alignment)
            info.aligned.append(winner.kind)
            t5 = time.perf_counter()
            timing["align"] = timing.get("align", 0.0) + t5 - t4
            t4 = t5
        cuboids.append(winner.box.to_cuboid(winner.gain))
        info.gains.append(winner.gain)
        state = combine(winner.values, state)
        timing["update"] += time.perf_counter() - t4
        if progress is not None:
            progress(info.iterations, len(cuboids), winner.gain)
    info.state = state.cpu().numpy()
    return cuboids, info


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
        ensure_compiled(solver, sampler)
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

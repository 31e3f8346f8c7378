"""The estimator (paper Sec. 3.2, Fig. 3): sample minimal sets -> solve -> score -> select, one cuboid
per step, until the best hypothesis no longer raises the occlusion-aware inlier count by Theta.

Entry points: :func:`fit_depth` (a depth map and its camera) and :func:`fit_points` (prepared points).
Both return ``(cuboids, FitInfo)``.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
import torch

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.assign import OCCLUDED
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.sampling import Sampler, SamplingContext, draw_minimal_sets, make_sampler
from cuboidcli.fitting.scoring import ScoreParams, select_best, values_torch
from cuboidcli.geometry.kernels import combine
from cuboidcli.solvers.base import CuboidSolver, SizeBounds

INVALID = -3

ProgressFn = Callable[[int, int, float], None]
"""progress(step, cuboids_so_far, last_gain) is called after every step."""


@dataclass
class FitInfo:
    """What happened while fitting one frame."""

    gains: list[float] = field(default_factory=list)
    """Inlier-count gain of each selected cuboid, in selection order."""
    theta: float = 0.0
    """Stopping threshold used (9 ln n by default)."""
    n_points: int = 0
    """Valid fitting points n."""
    iterations: int = 0
    """Sampling steps run, including a final step whose best hypothesis was rejected."""
    stop_reason: str = ""
    """max_cuboids | gain_below_theta | too_few_points."""
    rejected_gain: float | None = None
    """Gain of the best hypothesis of the rejecting step, if any."""
    timing_s: dict = field(default_factory=dict)
    """Per-stage seconds; 'total' is input loaded -> cuboids selected."""
    grid_step: int = 8
    assignment: np.ndarray | None = None
    """(Hs, Ws) int32 over the fitting grid: k >= 0 inlier of cuboid k, -1 none, -2 occluded, -3 no depth."""
    state: np.ndarray | None = None
    """(N,) f_OAI of the final set at the valid fitting points."""

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


def prepare_points(
    depth_m: np.ndarray, camera: Camera, grid_step: int, device: str = "cpu"
) -> PreparedPoints:
    """The fitting grid: every grid_step-th pixel (nearest, no averaging), invalid depth excluded."""
    grid = camera.backproject(np.where(valid_depth(depth_m), depth_m, 0.0), grid_step)
    depth_grid = grid[..., 2]
    flat = grid.reshape(-1, 3)
    ok = np.flatnonzero(flat[:, 2] > 0)
    return PreparedPoints(
        points=torch.from_numpy(flat[ok].astype(np.float32)).to(device),
        grid_index=torch.from_numpy(ok),
        grid_shape=depth_grid.shape,
        depth_grid=torch.from_numpy(depth_grid.astype(np.float32)).to(device),
    )


def make_solver(
    config: FitConfig,
    weights_dir: str | Path | None = None,
    onnx_path: str | Path | None = None,
    device: str = "cpu",
) -> CuboidSolver:
    bounds = SizeBounds(config.a_min, config.a_max)
    if config.solver == "numerical":
        from cuboidcli.solvers.numerical import NumericalSolver

        return NumericalSolver(bounds=bounds, lr=config.solver_lr, iters=config.solver_iters)
    if config.solver == "neural":
        from cuboidcli.bundles import weights_for
        from cuboidcli.solvers.neural import NeuralSolver, resolve_weights

        weights = resolve_weights(weights_for("solver", weights_dir))
        return NeuralSolver(weights=weights, device=device, bounds=bounds)
    if config.solver == "onnx":
        from cuboidcli.solvers.onnx import OnnxSolver

        if onnx_path is None:
            raise ValueError("the onnx solver needs an ONNX file (--onnx solver.onnx)")
        return OnnxSolver(str(onnx_path), bounds)
    raise ValueError(f"unknown solver {config.solver!r}; choose numerical, neural or onnx")


_COMPILED = False


def ensure_compiled() -> None:
    """Compile (or load from cache) the fused CPU kernels once per process, outside any timing."""
    global _COMPILED
    if _COMPILED:
        return
    from cuboidcli.fitting.fused import cuboid_values, score_gains
    from cuboidcli.solvers.adam_fused import adam_solve

    p = np.array([[0.0, 0.0, 2.0], [0.1, 0.0, 2.0]])
    c, a, R = np.array([[0.0, 0.0, 2.5]]), np.array([[0.5, 0.5, 0.5]]), np.eye(3)[None]
    score_gains(p, c, a, R, np.zeros(2), 0.004, 5.0, 0.008)
    cuboid_values(p, c, a, R, 0.004, 5.0, 0.008)
    init = np.zeros((1, 9))
    init[0, 6:] = 0.1
    adam_solve(np.zeros((1, 6, 3)), init, 1e-3, 2.0, 0.01, 1, init.copy())
    _COMPILED = True


def fit_points(
    prep: PreparedPoints,
    config: FitConfig,
    solver: CuboidSolver,
    sampler: Sampler,
    progress: ProgressFn | None = None,
    timing: dict | None = None,
) -> tuple[list[Cuboid], FitInfo]:
    """Sequential robust fitting on prepared points (Sec. 3.2). ``timing`` collects per-stage seconds."""
    timing = {} if timing is None else timing
    for k in ("sample", "solve", "score", "update"):
        timing.setdefault(k, 0.0)
    pts = prep.points
    n = pts.shape[0]
    info = FitInfo(theta=config.theta_for(n), n_points=n, grid_step=config.grid_step)
    sp = ScoreParams(config.tau_sq_m2, config.beta, config.tau_c, config.occlusion_aware)
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
        t = time.perf_counter()
        ctx = SamplingContext(
            pts, prep.grid_index, prep.grid_shape, prep.depth_grid, state.float(), len(cuboids)
        )
        with torch.no_grad():
            if hasattr(sampler, "draw"):
                idx = sampler.draw(ctx, config.hypotheses, config.min_set, gen)
            else:
                p, q = sampler.distributions(ctx)
                idx = draw_minimal_sets(p, q, config.hypotheses, config.min_set, gen)
        idx = idx.to(pts.device)
        t2 = time.perf_counter()
        timing["sample"] += t2 - t
        centers, half, rot = solver(pts[idx])
        t3 = time.perf_counter()
        timing["solve"] += t3 - t2
        best, gain, _ = select_best(
            pts, centers, half, rot, state, sp, gen, config.prescore_points, config.rescore_top
        )
        t4 = time.perf_counter()
        timing["score"] += t4 - t3
        if not gain > info.theta:
            info.stop_reason = "gain_below_theta"
            info.rejected_gain = gain
            break
        c_b, a_b, R_b = centers[best : best + 1], half[best : best + 1], rot[best : best + 1]
        values = _values_one(pts, c_b, a_b, R_b, sp)
        if config.refine:
            c_b, a_b, R_b, values, gain = _refine(pts, c_b, a_b, R_b, values, state, gain, sp, config, gen)
            t5 = time.perf_counter()
            timing["refine"] = timing.get("refine", 0.0) + t5 - t4
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


def _refine(pts, c, a, R, values, state, gain, sp: ScoreParams, config: FitConfig, gen: torch.Generator):
    """Refine the winner on the points it newly explains; keep the result only if the gain holds."""
    from cuboidcli.fitting.refine import refine_cuboid, refine_cuboid_fused

    inl = ((values >= 0.5) & (values > state)).nonzero().squeeze(1)
    if inl.numel() < config.min_set:
        return c, a, R, values, gain
    if inl.numel() > config.refine_max_points:
        inl = inl[torch.randperm(inl.numel(), generator=gen)[: config.refine_max_points].to(inl.device)]
    if pts.device.type == "cpu":
        out = refine_cuboid_fused(
            pts[inl].numpy(), c[0].numpy(), a[0].numpy(), R[0].numpy(), config.a_min, config.a_max
        )
        c2, a2, R2 = (torch.from_numpy(np.asarray(x)) for x in out)
    else:
        c2, a2, R2 = refine_cuboid(pts[inl], c[0], a[0], R[0], config.a_min, config.a_max)
    c2, a2, R2 = c2[None].to(c.dtype), a2[None].to(a.dtype), R2[None].to(R.dtype)
    v2 = _values_one(pts, c2, a2, R2, sp)
    g2 = float((combine(v2, state) - state).sum())
    if g2 >= gain - 0.005 * abs(gain):
        return c2, a2, R2, v2, g2
    return c, a, R, values, gain


def _values_one(pts, c, a, R, sp: ScoreParams) -> torch.Tensor:
    """f_OAI of one cuboid at every point (N,), float64."""
    if pts.device.type == "cpu":
        from cuboidcli.fitting.fused import cuboid_values

        v = cuboid_values(
            pts.double().numpy(),
            c.double().numpy(),
            a.double().numpy(),
            R.double().numpy(),
            sp.tau,
            sp.beta,
            sp.tau_c,
            sp.occlusion_aware,
        )
        return torch.from_numpy(v[0])
    return values_torch(pts.double(), c.double(), a.double(), R.double(), sp)[0]


def fit_depth(
    depth_m: np.ndarray,
    camera: Camera,
    config: FitConfig | None = None,
    *,
    solver: CuboidSolver | None = None,
    sampler: Sampler | None = None,
    weights_dir: str | Path | None = None,
    onnx_path: str | Path | None = None,
    progress: ProgressFn | None = None,
) -> tuple[list[Cuboid], FitInfo]:
    """Fit cuboids to a depth map (H, W) in metres (0/NaN/inf = missing) seen by ``camera``.

    Returns the selected cuboids (in selection order, each with its ``inlier_gain``) and a FitInfo.
    Deterministic for a given ``config.seed``.
    """
    config = config or FitConfig()
    device = config.device
    if device == "cpu":
        ensure_compiled()
    solver = solver or make_solver(config, weights_dir, onnx_path, device)
    sampler = sampler or make_sampler(config.sampler, weights_dir, device)
    t0 = time.perf_counter()
    prep = prepare_points(depth_m, camera, config.grid_step, device)
    timing = {"prepare": time.perf_counter() - t0}
    cuboids, info = fit_points(prep, config, solver, sampler, progress, timing)
    timing["total"] = time.perf_counter() - t0
    t = time.perf_counter()
    info.assignment = grid_assignment(prep, info.state, cuboids, config)
    timing["assign"] = time.perf_counter() - t
    info.timing_s = {k: round(v, 6) for k, v in timing.items()}
    return cuboids, info


def grid_assignment(
    prep: PreparedPoints, state: np.ndarray, cuboids: list[Cuboid], config: FitConfig
) -> np.ndarray:
    """Per fitting-grid cell label (Hs, Ws): cuboid index, -1 none, -2 occluded, -3 no depth."""
    from cuboidcli.fitting.assign import assign_points

    labels = np.full(prep.grid_shape[0] * prep.grid_shape[1], INVALID, dtype=np.int32)
    lab = assign_points(
        prep.points.cpu().numpy(),
        cuboids,
        config.tau_sq_m2,
        config.beta,
        config.tau_c,
        config.occlusion_aware,
    )
    if state is not None and len(cuboids):
        lab[state < 0] = OCCLUDED
    labels[prep.grid_index.numpy()] = lab
    return labels.reshape(prep.grid_shape)

"""Training the sampling-weight network to place the FIRST point of localised minimal sets.

With localised minimal sets (:mod:`cuboidcli.sampling.proposals`) a hypothesis is decided by where its
first point lands: six points from a ball around a seed on the sofa give a sofa box. So the question a
learned sampler can answer is "which seeds lead to the structure the estimator should take next?". No box
labels are needed to answer it from data: at every step of a sequential fit of a training scene, draw
|H| localised sets with seeds from the Sequential-RANSAC weights, solve and score them, and record for
every seed point the best inlier-count gain of the hypotheses grown from it, as a fraction of the step's
best gain (its *seed score* s in [0, 1]). The network (one map, built on the "unexplained" prior: the
map is softmax(logit + log(1 - max(state, 0)))) is trained by cross-entropy to the target distribution
T(i) ∝ prior(i) exp(kappa s(i)) over the seeded points, so that its optimal logit is kappa s(i) + const:
a seed whose sets reach the step's best structure is exp(kappa) times as likely as one whose sets explain
nothing. The state then advances with the best hypothesis, as in the estimator.

This is reward-weighted regression of the first-point distribution (a policy improvement step with the
sequential weights as behaviour policy), dense in the points and far less noisy than the paper's
REINFORCE on sets of 32 hypotheses.
"""

from __future__ import annotations

import json
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import PreparedPoints
from cuboidcli.fitting.scoring import ScoreParams, gains_cpu
from cuboidcli.fitting.winner import values_one
from cuboidcli.geometry.kernels import combine
from cuboidcli.io.atomic import atomic_torch_save
from cuboidcli.learn.sampler_data import dataset_splits, depth_statistics, prepare_scenes
from cuboidcli.nets.checkpoint import checkpoint_dict
from cuboidcli.nets.sampler import SamplerNet, SamplerNetConfig
from cuboidcli.sampling import SamplingContext, SequentialSampler, draw_hypotheses
from cuboidcli.sampling.learned import grid_inputs
from cuboidcli.solvers.base import SizeBounds
from cuboidcli.solvers.numerical import NumericalSolver


@dataclass(frozen=True)
class SeedTrainConfig:
    hypotheses: int = 1024
    """Localised sets drawn per step to score the seeds."""
    steps: int = 6
    """Sequential steps recorded per scene (fewer when the scene is explained earlier)."""
    kappa: float = 5.0
    """Sharpness of the target: a seed reaching the step's best gain is exp(kappa) times as likely."""
    epochs: int = 4
    lr: float = 1e-3
    width: int = 48
    blocks: int = 4
    upsample: int = 1
    """The network runs on the fitting grid itself (1) or on it upsampled (see SamplerNetConfig)."""
    scenes: int | None = None
    """Training scenes used (None = all)."""
    seed: int = 0
    max_minutes: float | None = None


@dataclass
class SeedRecord:
    scene: int
    state: torch.Tensor  # (N,) float32
    seeds: torch.Tensor  # (S,) long, unique seed points
    score: torch.Tensor  # (S,) float32 in [0, 1]


def scene_records(
    prep: PreparedPoints, scene: int, fit: FitConfig, cfg: SeedTrainConfig, gen: torch.Generator
) -> list[SeedRecord]:
    """Seed scores along a sequential fit of one scene (see the module docstring)."""
    pts = prep.points.cpu()
    n = pts.shape[0]
    solver = NumericalSolver(SizeBounds(fit.a_min, fit.a_max), lr=fit.solver_lr, iters=fit.solver_iters)
    sp = ScoreParams(fit.tau_sq_m2, fit.beta, fit.tau_c, True)
    theta = fit.theta_for(n)
    state = torch.zeros(n, dtype=torch.float64)
    out = []
    seq = SequentialSampler()
    P = pts.double().numpy()
    for _ in range(cfg.steps):
        ctx = SamplingContext(
            pts, prep.grid_index, prep.grid_shape, prep.depth_grid, state, 0, prep.focal_cells
        )
        _, idx, _ = draw_hypotheses(seq, ctx, cfg.hypotheses, fit.min_set, gen, 1.0, fit.local_radii_m)
        seeds = idx[:, 0]
        c, a, R = solver(pts[idx])
        g = gains_cpu(P, c.double().numpy(), a.double().numpy(), R.double().numpy(), state.numpy(), sp)
        best = int(np.argmax(g))
        if not g[best] > theta:
            break
        per_seed = torch.full((n,), -np.inf, dtype=torch.float64)
        per_seed.scatter_reduce_(0, seeds, torch.from_numpy(g), "amax")
        uniq = torch.isfinite(per_seed).nonzero().squeeze(1)
        score = (per_seed[uniq] / g[best]).clamp(0.0, 1.0).float()
        out.append(SeedRecord(scene, state.float().clone(), uniq, score))
        values = values_one(pts, c[best : best + 1], a[best : best + 1], R[best : best + 1], sp)
        state = combine(values, state)
    return out


def record_loss(net: SamplerNet, prep: PreparedPoints, rec: SeedRecord, kappa: float) -> torch.Tensor:
    ctx = SamplingContext(prep.points, prep.grid_index, prep.grid_shape, prep.depth_grid, rec.state, 0)
    depth, state, valid = grid_inputs(ctx)
    out = net(depth, state, valid)
    log_p = out.log_p[0, 0].flatten()[prep.grid_index][rec.seeds]  # (S,), prior included
    log_p = torch.log_softmax(log_p, 0)
    prior = (1.0 - rec.state[rec.seeds].clamp(0.0, 1.0)).clamp_min(net.config.prior_floor)
    target = torch.softmax(torch.log(prior) + kappa * rec.score, 0)
    return -(target * log_p).sum() + (target * torch.log(target.clamp_min(1e-30))).sum()  # KL(T || p)


def train_seed_sampler(
    data: str | Path,
    out_dir: str | Path,
    cfg: SeedTrainConfig,
    fit: FitConfig | None = None,
    on_event: Callable[[dict], None] | None = None,
) -> Path:
    """Record seed scores on the training scenes, train the one-map network, write
    ``out_dir/sampler_v3.pt`` (weights) and ``log.jsonl``. Returns the weights path."""
    fit = fit or FitConfig()
    emit = on_event or (lambda e: None)
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    torch.manual_seed(cfg.seed)
    train, val, how = dataset_splits(data)
    if cfg.scenes is not None:
        train = train[: cfg.scenes]
    scenes = prepare_scenes(train, fit.grid_step, fit.min_set * 10)
    mean, std = depth_statistics(scenes)
    gen = torch.Generator().manual_seed(cfg.seed + 1)
    t0 = time.perf_counter()
    records: list[SeedRecord] = []
    for i, s in enumerate(scenes):
        records += scene_records(s.prep, i, fit, cfg, gen)
        if (i + 1) % 20 == 0:
            emit({"event": "records", "scenes": i + 1, "records": len(records)})
    emit({"event": "records_done", "records": len(records), "seconds": time.perf_counter() - t0})
    net = SamplerNet(
        SamplerNetConfig(
            maps=1,
            width=cfg.width,
            blocks=cfg.blocks,
            upsample=cfg.upsample,
            prior="unexplained",
            depth_mean_m=mean,
            depth_std_m=std,
        )
    )
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr)
    log = (out / "log.jsonl").open("w", encoding="utf-8")
    order_gen = torch.Generator().manual_seed(cfg.seed + 2)
    stop = False
    for epoch in range(cfg.epochs):
        net.train()
        losses = []
        for j in torch.randperm(len(records), generator=order_gen).tolist():
            rec = records[j]
            loss = record_loss(net, scenes[rec.scene].prep, rec, cfg.kappa)
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            losses.append(float(loss.detach()))
            if cfg.max_minutes is not None and time.perf_counter() - t0 > 60 * cfg.max_minutes:
                stop = True
                break
        event = {
            "event": "epoch",
            "epoch": epoch,
            "kl": float(np.mean(losses)),
            "minutes": (time.perf_counter() - t0) / 60,
        }
        log.write(json.dumps(event) + "\n")
        log.flush()
        emit(event)
        meta = {
            "trainer": "seed",
            "config": asdict(cfg),
            "epochs_done": epoch + 1,
            "data": str(data),
            "split": how,
        }
        atomic_torch_save(checkpoint_dict(net.eval(), meta), out / "sampler_v3.pt")
        if stop:
            break
    log.close()
    return out / "sampler_v3.pt"

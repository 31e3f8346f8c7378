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

import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import numpy as np
import torch

from cuboidcli.fitting.box import values_one
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.fit_input import FitInput
from cuboidcli.fitting.scoring import ScoreParams, gains_cpu
from cuboidcli.geometry.kernels import combine
from cuboidcli.learn.job import OneNetJob, StepResult
from cuboidcli.learn.run_config import RunConfig
from cuboidcli.learn.sampler_data import dataset_splits, depth_statistics, prepare_scenes
from cuboidcli.learn.trainer import Run, run_job
from cuboidcli.learn.training_state import resumed
from cuboidcli.nets.checkpoint import checkpoint_dict
from cuboidcli.nets.sampler import SamplerNet, SamplerNetConfig
from cuboidcli.sampling import SamplingContext, SequentialSampler, draw_hypotheses
from cuboidcli.sampling.learned import grid_inputs
from cuboidcli.solvers.base import SizeBounds
from cuboidcli.solvers.numerical import NumericalSolver

STATE_KIND = "seed-train-state"
#: The weights file it writes.
WEIGHTS = "sampler_v3.pt"


@dataclass(frozen=True)
class SeedTrainConfig:
    hypotheses: int = 1024
    """Localised sets drawn per step to score the seeds."""
    steps: int = 6
    """Sequential steps recorded per scene (fewer when the scene is explained earlier)."""
    kappa: float = 5.0
    """Sharpness of the target: a seed reaching the step's best gain is exp(kappa) times as likely."""
    epochs: int = 4
    """Passes over the recorded seed scores."""
    lr: float = 1e-3
    """Adam learning rate."""
    width: int = 48
    """Channels of the network's convolutions."""
    blocks: int = 4
    """Residual blocks of the network."""
    upsample: int = 1
    """The network runs on the fitting grid itself (1) or on it upsampled (see SamplerNetConfig)."""
    scenes: int | None = None
    """Training scenes used (None = all)."""
    seed: int = 0
    """Seeds the initial weights, the hypotheses drawn while recording and the order of the records."""
    max_minutes: float | None = None
    """Time budget in minutes, counted from the start (the recording included); the run then ends with
    the weights of its last finished epoch."""


@dataclass
class SeedRecord:
    scene: int
    state: torch.Tensor  # (N,) float32
    seeds: torch.Tensor  # (S,) long, unique seed points
    score: torch.Tensor  # (S,) float32 in [0, 1]


def scene_records(
    prep: FitInput, scene: int, fit: FitConfig, cfg: SeedTrainConfig, gen: torch.Generator
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
            pts, prep.grid.index, prep.grid.shape, prep.grid.depth, state, 0, prep.grid.focal_cells
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


def record_loss(net: SamplerNet, prep: FitInput, rec: SeedRecord, kappa: float) -> torch.Tensor:
    ctx = SamplingContext(prep.points, prep.grid.index, prep.grid.shape, prep.grid.depth, rec.state, 0)
    depth, state, valid = grid_inputs(ctx)
    out = net(depth, state, valid)
    log_p = out.log_p[0, 0].flatten()[prep.grid.index][rec.seeds]  # (S,), prior included
    log_p = torch.log_softmax(log_p, 0)
    prior = (1.0 - rec.state[rec.seeds].clamp(0.0, 1.0)).clamp_min(net.config.prior_floor)
    target = torch.softmax(torch.log(prior) + kappa * rec.score, 0)
    return -(target * log_p).sum() + (target * torch.log(target.clamp_min(1e-30))).sum()  # KL(T || p)


class SeedJob(OneNetJob):
    """The first-point map's training as a job of :func:`~cuboidcli.learn.trainer.run_job`: the seed scores
    are recorded in :meth:`setup` (again when resuming: they depend only on the seed), then each epoch
    visits every record once in a seeded random order. No validation: every epoch's weights are kept."""

    name = "seed"
    net_name = "sampler"
    state_kind = STATE_KIND
    distributed = False

    def __init__(self, cfg: SeedTrainConfig, data: str | Path, fit: FitConfig):
        self.cfg, self.data, self.fit = cfg, data, fit

    def setup(self, run: Run, state: dict | None) -> None:
        cfg, fit = self.cfg, self.fit
        train, _, self.split = dataset_splits(self.data)
        if cfg.scenes is not None:
            train = train[: cfg.scenes]
        self.scenes = prepare_scenes(train, fit, fit.min_set * 10)
        mean, std = depth_statistics(self.scenes)
        gen = torch.Generator().manual_seed(cfg.seed + 1)
        t0 = time.perf_counter()
        self.records: list[SeedRecord] = []
        for i, s in enumerate(self.scenes):
            self.records += scene_records(s.prep, i, fit, cfg, gen)
            if (i + 1) % 20 == 0:
                run.emit({"event": "records", "scenes": i + 1, "records": len(self.records)})
        run.emit({"event": "records_done", "records": len(self.records), "seconds": time.perf_counter() - t0})
        self.net_cfg = SamplerNetConfig(
            maps=1,
            width=cfg.width,
            blocks=cfg.blocks,
            upsample=cfg.upsample,
            prior="unexplained",
            depth_mean_m=mean,
            depth_std_m=std,
        )
        self.net = SamplerNet(self.net_cfg)
        self.optimizer = torch.optim.Adam(self.net.parameters(), lr=cfg.lr)
        self.order_gen = torch.Generator().manual_seed(cfg.seed + 2)
        if state is not None:
            self.net.load_state_dict(state["state_dict"])
            self.order_gen.set_state(state["order_rng"])

    def batches(self, run: Run):
        self.net.train()
        return torch.randperm(len(self.records), generator=self.order_gen).tolist()

    def step(self, run: Run, j: int) -> StepResult:
        rec = self.records[j]
        loss = record_loss(self.net, self.scenes[rec.scene].prep, rec, self.cfg.kappa)
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        self.optimizer.step()
        return StepResult({"kl": float(loss.detach())})

    def validate(self, run: Run) -> None:
        return None

    def more_state(self, run: Run) -> dict:
        return {"order_rng": self.order_gen.get_state(), "fit_config": self.fit.to_dict()}

    def best_weights(self, run: Run, validation: dict) -> dict[str, dict]:
        meta = {
            "trainer": "seed",
            "config": asdict(self.cfg),
            "epochs_done": run.epoch,
            "data": str(self.data),
            "split": self.split,
        }
        return {WEIGHTS: checkpoint_dict(self.net, meta)}

    def settings(self, run: Run) -> dict:
        data = {"data": str(self.data), "split": self.split}
        return {"train": asdict(self.cfg), "fit": self.fit.to_dict(), **data}

    def start_fields(self, run: Run) -> dict:
        return {"scenes": len(self.scenes), "records": len(self.records)}

    def end_fields(self, run: Run) -> dict:
        return {"weights": str(run.out_dir / WEIGHTS)}


#: Fields of the caller's config that replace the checkpoint's when resuming.
RESUME_OVERRIDES = ("epochs", "max_minutes")


def train_seed_sampler(
    data: str | Path,
    out_dir: str | Path,
    cfg: SeedTrainConfig,
    fit: FitConfig | None = None,
    on_event: Callable[[dict], None] | None = None,
    resume: str | Path | None = None,
) -> Path:
    """Record seed scores on the training scenes, train the one-map network, write
    ``out_dir/sampler_v3.pt`` (the weights, after every epoch), ``last.pt`` and ``log.jsonl``. Returns the
    weights path. ``resume``: a ``last.pt`` of this trainer; its settings apply except ``epochs`` and
    ``max_minutes`` of ``cfg``. ``max_minutes`` counts from the start, the recording included."""
    fit = fit or FitConfig()
    state, cfg = resumed(resume, cfg, RESUME_OVERRIDES, STATE_KIND, "seed-sampler training")
    if state is not None:
        fit = FitConfig(**state["fit_config"])
    run = RunConfig.of(
        cfg, out_dir, resume, max_epochs=cfg.epochs, stop_within_epoch=True, log_every=None, threads=None
    )
    run_job(SeedJob(cfg, data, fit), run, state, on_event)
    return Path(out_dir) / WEIGHTS

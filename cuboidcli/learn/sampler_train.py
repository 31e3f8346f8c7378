"""Training of the sampling-weight network by itself (paper Sec. 3.5, appendix "Sampling Weight Network").

Per scene, |M| instances run in sequence: the network sees the depth and the current state, K sets of |H|
hypotheses are drawn from its maps, solved with the numerical solver and scored, the loss of
:func:`cuboidcli.learn.sampler_loss.instance_loss` is back-propagated, and the state is updated with the
best hypothesis before the next instance. B scenes make one Adam step. The occlusion penalty threshold
tau_c follows the paper's schedule per epoch (:func:`~cuboidcli.learn.sampler_loss.occlusion_threshold`).

Data: a dataset folder in the generic layout, split as :mod:`cuboidcli.learn.sampler_data` describes.

Validation after every epoch fits the val frames with the learned sampler at ``val_hypotheses`` and the
test-time settings (tau_c = 2 tau) and computes the paper's metrics (:mod:`cuboidcli.evaluation.metrics`);
AUC@20 cm selects the best weights. Without the evaluation package the mean inlier fraction of the fitted
cuboids is used instead.

Files in ``out_dir``: ``config.json`` (resolved configs), ``log.jsonl`` (one JSON record per step,
validation and epoch), ``last.pt`` and ``epoch_XXX.pt`` (training state: weights, optimizer, RNG states,
epoch; the last ``keep_snapshots`` are kept) and ``sampler_v2.pt`` (weights only, the best validation so
far, in the format :meth:`cuboidcli.sampling.learned.LearnedSampler.load` reads; ``--weights out_dir``
finds it there). ``resume`` continues a run exactly: the same frames, draws and losses as without
interruption. This module prints nothing: progress goes to the ``on_event`` callback.

Multi-process (``torchrun``, see :mod:`cuboidcli.learn.distributed`): every rank holds a replica of the
net and prepares every training scene. The B scenes of a step are split over the W ranks, rank r taking
the step's scenes r, r + W, ... (a rank may get none, e.g. in a last partial batch), so ``batch`` stays
the global number of scenes per step and the epoch has as many steps as in one process; use a ``batch``
that is a multiple of W to keep every rank busy. Each rank scales its losses by 1 / (B |M|) of the global
batch, and the gradients are summed over the ranks by one all-reduce per step before the Adam step
(:meth:`~cuboidcli.learn.distributed.DistContext.sum_gradients`, not DistributedDataParallel: the net
runs |M| times per scene, each with its own backward), so every rank steps with the mean gradient of the
global batch and the replicas stay bit-identical. Rank r draws its hypotheses from its own generator
(:func:`draw_seed`; rank 0 keeps the single-process stream), so a run is reproducible for a given seed
and number of processes but differs from a single-process run. The val frames are split over the ranks
the same way and their per-frame results gathered in frame order, so the validation numbers equal a
single process's (fitting is seeded per frame) and every rank takes the same best-weights decision.
Rank 0 alone writes files and calls ``on_event``; the ``max_minutes`` decision is taken on its clock and
broadcast, so all ranks stop after the same epoch. Checkpoints hold every rank's draw generator state
(``draw_rngs``): resuming with the same number of processes continues the run exactly; with another
number, the ranks the checkpoint has a state for restore it and the others start a fresh stream
(:func:`draw_seed` of their rank and the epoch), a valid continuation but not the uninterrupted run.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import asdict, replace
from pathlib import Path

import numpy as np
import torch

from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.fit_input import FitInput
from cuboidcli.fitting.pipeline import fit_depth
from cuboidcli.geometry.kernels import combine
from cuboidcli.io.dataset import Frame
from cuboidcli.learn.distributed import DistContext
from cuboidcli.learn.draws import draw_generator, draw_states
from cuboidcli.learn.job import OneNetJob, StepResult, Validation
from cuboidcli.learn.run_config import RunConfig
from cuboidcli.learn.sampler_config import SamplerTrainConfig
from cuboidcli.learn.sampler_data import dataset_splits, depth_statistics, epoch_order, prepare_scenes
from cuboidcli.learn.sampler_loss import LossParams, instance_loss
from cuboidcli.learn.trainer import Run, batched, run_job, shared_batch_step
from cuboidcli.learn.training_state import resumed
from cuboidcli.nets.checkpoint import checkpoint_dict
from cuboidcli.nets.sampler import SamplerNet, SamplerNetConfig
from cuboidcli.sampling import SamplingContext
from cuboidcli.sampling.learned import LearnedSampler, grid_inputs
from cuboidcli.solvers.base import SizeBounds
from cuboidcli.solvers.numerical import NumericalSolver
from cuboidcli.weights import FILES

STATE_KIND = "sampler-train-state"


def train_scene(
    net: SamplerNet,
    prep: FitInput,
    solver: NumericalSolver,
    lp: LossParams,
    instances: int,
    generator: torch.Generator,
    scale: float,
) -> list[dict]:
    """Run |M| instances on one scene, back-propagating ``scale`` times each instance's loss.

    Gradients accumulate in ``net``; returns one record of floats per instance.
    """
    device = next(net.parameters()).device
    pts = prep.points.cpu()
    state = torch.zeros(pts.shape[0], dtype=torch.float64)
    records = []
    for m in range(instances):
        ctx = SamplingContext(pts, prep.grid.index, prep.grid.shape, prep.grid.depth.cpu(), state.float(), m)
        depth, state_grid, valid = (t.to(device) for t in grid_inputs(ctx))
        out = net(depth, state_grid, valid)
        at_points = prep.grid.index.to(device)
        log_p = out.log_p[0].flatten(1)[:, at_points]  # (Q, N) at the fitting points
        log_p_free = out.log_p_free[0].flatten(1)[:, at_points]
        res = instance_loss(log_p, out.log_q[0], pts, state, solver, lp, generator, log_p_corr=log_p_free)
        (res.loss * scale).backward()
        records.append(
            {
                "loss": float(res.loss.detach()),
                "expected_loss": res.expected_loss,
                "best_gain": res.best_gain,
                "mean_gain": res.mean_gain,
                "corr": res.corr,
                "entropy": res.entropy,
                "im": res.im,
                "maps_drawn": len(res.maps_drawn),
            }
        )
        state = combine(res.best_values, state)
    return records


def metrics_available() -> bool:
    try:
        import cuboidcli.evaluation.metrics  # noqa: F401
    except ImportError:
        return False
    return True


def validate(
    net: SamplerNet,
    frames: list[Frame],
    fit: FitConfig,
    cfg: SamplerTrainConfig,
    ctx: DistContext | None = None,
) -> tuple[dict, str, float]:
    """Fit the frames with the current net; returns (metrics, selection key, selection value).

    Metrics in reporting units (cm, %); ``mean_inlier_fraction``: mean over frames of I_c / N of the fitted
    cuboids. The selection value is AUC@20 cm (%) if the evaluation package is available, else that
    fraction. With an active ``ctx`` (a collective: every rank calls it) rank r fits frames r, r + W, ...
    and the per-frame results are gathered in frame order, so every rank returns the same numbers, equal
    to one process's; ``seconds`` is this rank's wall time.
    """
    ctx = ctx or DistContext()
    config = replace(
        fit, hypotheses=cfg.val_hypotheses, sampler="learned", grid_step=cfg.grid_step, seed=0, device="cpu"
    )
    sampler = LearnedSampler(net, device=next(net.parameters()).device)
    solver = NumericalSolver(SizeBounds(fit.a_min, fit.a_max), lr=fit.solver_lr, iters=fit.solver_iters)
    with_metrics = metrics_available()
    start = time.perf_counter()
    results = []  # (inlier fraction, cuboids, metrics or None) of this rank's frames
    for frame in ctx.share(frames):
        depth = frame.depth_m()
        cuboids, info = fit_depth(depth, frame.camera, config, solver=solver, sampler=sampler)
        metrics = None
        if with_metrics:
            from cuboidcli.evaluation.metrics import frame_metrics

            metrics = frame_metrics(frame.name, depth, frame.camera, cuboids)
        results.append((sum(info.gains) / max(info.n_points, 1), len(cuboids), metrics))
    net.train()
    ordered = ctx.gather_shares(results, len(frames))
    fractions = [r[0] for r in ordered]
    counts = [r[1] for r in ordered]
    per_frame = [r[2] for r in ordered]
    out = {"mean_inlier_fraction": float(np.mean(fractions)), "cuboids": float(np.mean(counts))}
    if with_metrics:
        from cuboidcli.evaluation.aggregate import aggregate
        from cuboidcli.evaluation.auc import auc_key

        agg = aggregate(per_frame)
        agg.pop("time_s", None)
        out.update(agg)
        key = auc_key(20.0)
    else:
        key = "mean_inlier_fraction"
    out["seconds"] = time.perf_counter() - start
    return out, key, float(out[key])


class SamplerJob(OneNetJob):
    """Training of the sampling-weight network as a job of :func:`~cuboidcli.learn.trainer.run_job`:
    epoch-based, B scenes a step split over the ranks, validated after every epoch."""

    name = "sampler"
    net_name = "sampler"
    state_kind = STATE_KIND
    rate_key = "scenes_per_s"

    def __init__(self, cfg: SamplerTrainConfig, data, net_cfg: SamplerNetConfig | None, fit: FitConfig):
        self.cfg, self.data, self.net_cfg, self.fit = cfg, data, net_cfg, fit

    def setup(self, run: Run, state: dict | None) -> None:
        cfg, fit = self.cfg, self.fit
        train_frames, val_frames, self.split_note = dataset_splits(self.data)
        self.scenes = prepare_scenes(train_frames, cfg.grid_step, fit.min_set, cfg.workers)
        if not self.scenes:
            raise ValueError(
                f"no usable training frames in {self.data} (each needs >= {fit.min_set} valid points)"
            )
        self.val_frames = val_frames[: cfg.val_frames] if cfg.val_frames is not None else val_frames
        if state is None:
            mean_m, std_m = depth_statistics(self.scenes)
            self.net_cfg = replace(self.net_cfg or SamplerNetConfig(), depth_mean_m=mean_m, depth_std_m=std_m)
        self.net = SamplerNet(self.net_cfg).to(run.device).train()
        if state is not None:
            self.net.load_state_dict(state["state_dict"])
        self.optimizer = torch.optim.Adam(self.net.parameters(), lr=cfg.lr)
        self.gen = draw_generator(cfg.seed, run.ctx, state, run.epoch)
        self.solver = NumericalSolver(
            SizeBounds(fit.a_min, fit.a_max), lr=fit.solver_lr, iters=fit.solver_iters
        )

    def batches(self, run: Run):
        cfg = self.cfg
        self.lp = cfg.loss_params(self.fit, run.epoch)
        return batched(epoch_order(len(self.scenes), run.epoch, cfg.seed, cfg.scenes_per_epoch), cfg.batch)

    def step(self, run: Run, batch: list[int]) -> StepResult:
        """B scenes; under DDP this rank trains its share of them, the records are those of all ranks."""
        cfg, lp = self.cfg, self.lp
        # The mean over the step's scenes and instances, on all ranks together: the sum over the ranks of
        # these partial gradients is the gradient of the global batch.
        scale = 1.0 / (len(batch) * cfg.instances)

        def one(i: int) -> list[dict]:
            return train_scene(self.net, self.scenes[i].prep, self.solver, lp, cfg.instances, self.gen, scale)

        mean = shared_batch_step(run.ctx, self.optimizer, self.net.parameters(), batch, one)
        names = [self.scenes[i].name for i in batch]
        step_fields = {"epoch": run.epoch + 1, "tau_c_sq_m2": lp.tau_c_sq_m2, "scenes": names}
        return StepResult(mean, step_fields, items=len(batch))

    def validate(self, run: Run) -> Validation | None:
        if not self.val_frames:
            return None
        metrics, key, value = validate(self.net, self.val_frames, self.fit, self.cfg, run.ctx)
        return Validation(value, {"key": key, **metrics})

    def more_state(self, run: Run) -> dict:
        return {**draw_states(self.gen, run.ctx), "fit_config": self.fit.to_dict()}

    def best_weights(self, run: Run, validation: dict) -> dict[str, dict]:
        meta = {
            "epoch": run.epoch,
            "val": validation,
            "train_config": asdict(self.cfg),
            "fit_config": self.fit.to_dict(),
            "data": str(self.data),
        }
        return {FILES["sampler"]: checkpoint_dict(self.net, meta)}

    def settings(self, run: Run) -> dict:
        return {
            "train": asdict(self.cfg),
            "net": self.net_cfg.to_dict(),
            "fit": self.fit.to_dict(),
            "data": str(self.data),
            **self._frames(),
        }

    def _frames(self) -> dict:
        frames = {"train_frames": len(self.scenes), "val_frames": len(self.val_frames)}
        return {"split": self.split_note, **frames}

    def start_fields(self, run: Run) -> dict:
        return self._frames()

    def end_fields(self, run: Run) -> dict:
        return {"epochs_done": run.epoch, "best": run.best, "weights": str(run.out_dir / FILES["sampler"])}

    def agreement(self) -> object:
        return (self.net_cfg.to_dict(), [s.name for s in self.scenes], [f.name for f in self.val_frames])


#: Fields of the caller's config that replace the checkpoint's when resuming.
RESUME_OVERRIDES = ("epochs", "threads", "device", "workers", "max_minutes", "keep_snapshots")


def train_sampler(
    cfg: SamplerTrainConfig,
    data: str | Path,
    out_dir: str | Path,
    net_cfg: SamplerNetConfig | None = None,
    fit: FitConfig | None = None,
    resume: str | Path | None = None,
    on_event: Callable[[dict], None] | None = None,
    stop_after_epoch: int | None = None,
    backend: str | None = None,
) -> dict:
    """Run (or resume) training; returns the final record (epochs done, best value, paths).

    When resuming, the schedule, the net shape and the fitting settings come from the checkpoint; only
    the fields of ``cfg`` in :data:`RESUME_OVERRIDES` apply (extending ``epochs`` also stretches the tau_c
    schedule). ``stop_after_epoch`` ends the run after that many completed epochs (as an interruption
    would). torch's thread count is set to ``cfg.threads`` for the run and restored afterwards.

    Launched by ``torchrun`` with ``WORLD_SIZE > 1``, this joins the process group for the duration of
    the call (``backend``: None = nccl on CUDA, gloo on CPU, or ``$CUBOIDS_DIST_BACKEND``) and trains data
    parallel as the module docstring describes; every rank must pass the same arguments. Only rank 0
    calls ``on_event`` and writes to ``out_dir``, which must be visible to every rank for ``resume``.
    The final record holds ``world_size`` and ``param_sha256``, one hash of the final weights per rank,
    all equal when the replicas stayed in sync.
    """
    fit = fit or FitConfig()
    hint = "last.pt or epoch_*.pt"
    state, cfg = resumed(resume, cfg, RESUME_OVERRIDES, STATE_KIND, "sampler training", hint)
    if state is not None:
        net_cfg = SamplerNetConfig.from_dict(state["config"])
        fit = FitConfig(**state["fit_config"])
    run = RunConfig.of(
        cfg,
        out_dir,
        resume,
        max_epochs=cfg.epochs,
        snapshot_name="epoch_{epoch:03d}.pt",
        stop_after_epochs=stop_after_epoch,
        backend=backend,
    )
    return run_job(SamplerJob(cfg, data, net_cfg, fit), run, state, on_event)

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
far, in the format :meth:`cuboidcli.sampling.learned.LearnedSampler.load` reads, so ``--weights out_dir``
uses it). ``resume`` continues a run exactly: the same frames, draws and losses as without interruption.
This module prints nothing: progress goes to the ``on_event`` callback.

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

import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import torch

from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import PreparedPoints, fit_depth
from cuboidcli.geometry.kernels import combine
from cuboidcli.io.atomic import atomic_torch_save, atomic_write_json
from cuboidcli.io.checkpoints import read_checkpoint
from cuboidcli.io.dataset import Frame
from cuboidcli.learn.distributed import DistContext, distributed, state_sha256
from cuboidcli.learn.sampler_data import dataset_splits, depth_statistics, epoch_order, prepare_scenes
from cuboidcli.learn.sampler_loss import CORR_MODES, LossParams, instance_loss, occlusion_threshold
from cuboidcli.nets.checkpoint import checkpoint_dict, parameter_count
from cuboidcli.nets.sampler import SamplerNet, SamplerNetConfig
from cuboidcli.sampling import SamplingContext
from cuboidcli.sampling.learned import LearnedSampler, grid_inputs
from cuboidcli.solvers.base import SizeBounds
from cuboidcli.solvers.numerical import NumericalSolver
from cuboidcli.weights import FILES

STATE_KIND = "sampler-train-state"
#: Rank r's draw seed is offset by r * RANK_SEED_STRIDE and a rank new to a resumed run's by the epoch times
#: EPOCH_SEED_STRIDE: the streams cannot meet as long as 0 <= seed < 2^32, epochs < 2^16 and ranks < 2^15.
RANK_SEED_STRIDE = 2**48
EPOCH_SEED_STRIDE = 2**32


def draw_seed(seed: int, rank: int = 0, epoch: int = 0) -> int:
    """Seed of the hypothesis-draw generator of ``rank``, started at ``epoch`` (0 for a fresh run, the
    resume epoch for a rank the checkpoint has no state for). Rank 0 of a fresh run: ``seed + 1``, the
    single-process stream."""
    return seed + 1 + rank * RANK_SEED_STRIDE + epoch * EPOCH_SEED_STRIDE


@dataclass(frozen=True)
class SamplerTrainConfig:
    """Schedule and bookkeeping of a sampler training run; defaults are the paper's NYU values except lr."""

    epochs: int = 25
    """N_e: epochs (also the length of the tau_c schedule)."""
    lr: float = 1e-4
    """Adam learning rate. The paper uses 1e-5 for 25 epochs of the 795 NYU training frames (~10k Adam
    steps at B = 2); a CPU budget of a few thousand steps moves each weight by at most ~steps * lr, so the
    default is 10x the paper's. Lower it (or use 1e-5) for long runs if the validation AUC oscillates."""
    batch: int = 2
    """B: scenes per optimizer step."""
    hypotheses: int = 32
    """|H|: hypotheses per sampled set."""
    instances: int = 8
    """|M|: sequential instances per scene."""
    samples_k: int = 2
    """K: hypothesis sets per instance (the baseline needs K >= 2)."""
    alpha: float = 10.0
    """alpha: selection softmax scale on gains in fractions of the points."""
    kappa_corr: float = 1.0
    corr_mode: str = "positive"
    """l_corr variant (see sampler_loss.LossParams.corr_mode); "paper" is the paper's plain sum."""
    kappa_entropy: float = 1.0
    kappa_im: float = 0.01
    loss_clamp: float = 0.3
    """Clamp of the baseline-subtracted task loss (see sampler_loss)."""
    tau_c_start_sq_m2: float = 1.0
    """tau_c at epoch 0, m^2 (the "1" of the paper's schedule)."""
    scenes_per_epoch: int | None = None
    """Scenes per epoch; None = every training frame once (the paper used 500 random scenes for SMH)."""
    grid_step: int = 8
    """Fitting points: every grid_step-th pixel (8 -> 60x80 at 480x640)."""
    seed: int = 0
    """Seeds the initial weights, the frame order of each epoch and every draw."""
    threads: int = 1
    """torch CPU threads."""
    device: str = "cpu"
    workers: int = 1
    """Threads reading and preparing frames."""
    val_hypotheses: int = 256
    """|H| when fitting the validation frames (the paper tests with 4096)."""
    val_frames: int | None = None
    """Validate on at most this many val frames (None = all)."""
    validate_initial: bool = True
    """Validate the untrained net before the first epoch (a reference point in the log)."""
    keep_snapshots: int = 3
    """epoch_XXX.pt files kept."""
    max_minutes: float | None = None
    """Stop after the epoch during which this much wall time (in this process) has passed."""

    def __post_init__(self) -> None:
        if self.corr_mode not in CORR_MODES:
            raise ValueError(f"corr_mode must be one of {CORR_MODES}, got {self.corr_mode!r}")
        if self.samples_k < 2:
            raise ValueError("samples_k (K) must be at least 2: the baseline of K = 1 cancels the signal")
        for name in ("epochs", "batch", "hypotheses", "instances", "grid_step", "threads", "workers"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")

    def loss_params(self, fit: FitConfig, epoch: int) -> LossParams:
        return LossParams(
            hypotheses=self.hypotheses,
            samples_k=self.samples_k,
            min_set=fit.min_set,
            alpha=self.alpha,
            tau_sq_m2=fit.tau_sq_m2,
            beta=fit.beta,
            tau_c_sq_m2=occlusion_threshold(epoch, self.epochs, fit.tau_sq_m2, self.tau_c_start_sq_m2),
            loss_clamp=self.loss_clamp,
            kappa_corr=self.kappa_corr,
            corr_mode=self.corr_mode,
            kappa_entropy=self.kappa_entropy,
            kappa_im=self.kappa_im,
        )


def train_scene(
    net: SamplerNet,
    prep: PreparedPoints,
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
        ctx = SamplingContext(pts, prep.grid_index, prep.grid_shape, prep.depth_grid.cpu(), state.float(), m)
        depth, state_grid, valid = (t.to(device) for t in grid_inputs(ctx))
        out = net(depth, state_grid, valid)
        at_points = prep.grid_index.to(device)
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


def _mean_records(records: list[dict]) -> dict:
    return {k: float(np.mean([r[k] for r in records])) for k in records[0]}


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
        from cuboidcli.evaluation.metrics import aggregate, auc_key

        agg = aggregate(per_frame)
        agg.pop("time_s", None)
        out.update(agg)
        key = auc_key(20.0)
    else:
        key = "mean_inlier_fraction"
    out["seconds"] = time.perf_counter() - start
    return out, key, float(out[key])


def _load_state(path: str | Path) -> dict:
    state = read_checkpoint(path)
    if state.get("kind") != STATE_KIND:
        raise ValueError(f"{path} is not a sampler training checkpoint (use last.pt or epoch_*.pt)")
    return state


class _Run:
    """The state of one training process: data, net, optimizer, generators, log."""

    def __init__(self, ctx: DistContext, cfg, data, out_dir: Path, net_cfg, fit: FitConfig, state, emit):
        self.ctx, self.cfg, self.fit, self.data, self.out_dir, self.emit = ctx, cfg, fit, data, out_dir, emit
        self.device = torch.device(cfg.device)
        if ctx.active and self.device.type == "cuda":
            self.device = torch.device("cuda", ctx.local_rank)  # one GPU per process on the node
        train_frames, val_frames, self.split_note = dataset_splits(data)
        self.scenes = prepare_scenes(train_frames, cfg.grid_step, fit.min_set, cfg.workers)
        if not self.scenes:
            raise ValueError(
                f"no usable training frames in {data} (each needs >= {fit.min_set} valid points)"
            )
        self.val_frames = val_frames[: cfg.val_frames] if cfg.val_frames is not None else val_frames
        if state is None:
            mean_m, std_m = depth_statistics(self.scenes)
            net_cfg = replace(net_cfg or SamplerNetConfig(), depth_mean_m=mean_m, depth_std_m=std_m)
        self.net_cfg = net_cfg
        torch.manual_seed(cfg.seed)
        self.net = SamplerNet(net_cfg).to(self.device).train()
        self.opt = torch.optim.Adam(self.net.parameters(), lr=cfg.lr)
        self.gen = torch.Generator().manual_seed(draw_seed(cfg.seed, ctx.rank))  # the hypothesis draws
        self.solver = NumericalSolver(
            SizeBounds(fit.a_min, fit.a_max), lr=fit.solver_lr, iters=fit.solver_iters
        )
        self.epoch, self.best, self.step = 0, -math.inf, 0
        if state is not None:
            self.net.load_state_dict(state["state_dict"])
            self.opt.load_state_dict(state["optimizer"])
            # Nothing draws from the global RNG during training (the draws and the frame order have seeded
            # generators of their own), so rank 0's saved state serves every rank.
            torch.set_rng_state(state["torch_rng"])
            self.epoch, self.best, self.step = int(state["epoch"]), float(state["best"]), int(state["step"])
            draw_rngs = state.get("draw_rngs") or [state["draw_rng"]]  # older checkpoints: rank 0's only
            if ctx.rank < len(draw_rngs):
                self.gen.set_state(draw_rngs[ctx.rank])
            else:  # resumed on more processes than the checkpoint was written by
                self.gen.manual_seed(draw_seed(cfg.seed, ctx.rank, self.epoch))
        if ctx.active:
            # A collective check that every rank sees the same data, net and (resumed) weights: ranks that
            # differ here would train replicas that silently drift apart.
            mine = (
                state_sha256(self.net.state_dict()),
                self.net_cfg.to_dict(),
                [s.name for s in self.scenes],
                [f.name for f in self.val_frames],
            )
            if any(other != mine for other in ctx.gather(mine)):
                raise ValueError(
                    "the processes disagree on the training data, the net or its weights: every rank must "
                    "read the same dataset folder (and --resume checkpoint)"
                )

    def log(self, record: dict) -> None:
        if not self.ctx.is_main:
            return
        with (self.out_dir / "log.jsonl").open("a", encoding="utf-8") as f:
            f.write(json.dumps(record) + "\n")
        self.emit(record)

    def train_epoch(self) -> dict:
        """One epoch of Adam steps over B scenes each; returns the mean of the per-instance records.

        Under DDP this rank trains its share of each step's scenes; the records are those of all ranks."""
        cfg, ctx = self.cfg, self.ctx
        lp = cfg.loss_params(self.fit, self.epoch)
        order = epoch_order(len(self.scenes), self.epoch, cfg.seed, cfg.scenes_per_epoch)
        step_means = []
        for b in range(0, len(order), cfg.batch):
            t_step = time.perf_counter()
            batch = order[b : b + cfg.batch]
            self.opt.zero_grad(set_to_none=True)
            records = []
            # The mean over the step's scenes and instances, on all ranks together: the sum over the ranks
            # of these partial gradients is the gradient of the global batch.
            scale = 1.0 / (len(batch) * cfg.instances)
            for i in ctx.share(batch):
                records += train_scene(
                    self.net, self.scenes[i].prep, self.solver, lp, cfg.instances, self.gen, scale
                )
            ctx.sum_gradients(self.net.parameters())
            self.opt.step()
            self.step += 1
            records = [r for shard in ctx.gather(records) for r in shard]  # in scene order per rank
            step_means.append(_mean_records(records))
            self.log(
                {
                    "event": "step",
                    "epoch": self.epoch + 1,
                    "step": self.step,
                    "tau_c_sq_m2": lp.tau_c_sq_m2,
                    "scenes": [self.scenes[i].name for i in batch],
                    **step_means[-1],
                    "seconds": time.perf_counter() - t_step,
                }
            )
        self.epoch += 1
        return _mean_records(step_means)

    def validate(self, initial: bool = False) -> tuple[bool, dict]:
        """Validate; returns (new best?, record). Without val frames the latest weights count as best."""
        if not self.val_frames:
            return not initial, {}
        metrics, key, value = validate(self.net, self.val_frames, self.fit, self.cfg, self.ctx)
        improved = not initial and value > self.best
        if not initial:
            self.best = max(self.best, value)
        record = {"key": key, **metrics}
        tag = {"initial": True} if initial else {"best": improved}
        self.log({"event": "val", "epoch": self.epoch, **tag, **record})
        return improved, record

    def save(self, improved: bool, val_record: dict) -> None:
        """Training state to last.pt and epoch_XXX.pt; the weights to sampler_v2.pt if they are the best.

        A collective (every rank's draw generator state goes into the checkpoint); rank 0 writes."""
        cfg = self.cfg
        draw_rngs = self.ctx.gather(self.gen.get_state())
        if not self.ctx.is_main:
            return
        blob = {
            "kind": STATE_KIND,
            "config": self.net_cfg.to_dict(),
            "state_dict": self.net.state_dict(),
            "optimizer": self.opt.state_dict(),
            "torch_rng": torch.get_rng_state(),
            "draw_rng": self.gen.get_state(),
            "draw_rngs": draw_rngs,
            "world_size": self.ctx.world_size,
            "epoch": self.epoch,
            "step": self.step,
            "best": self.best,
            "train_config": asdict(cfg),
            "fit_config": self.fit.to_dict(),
        }
        atomic_torch_save(blob, self.out_dir / "last.pt")
        atomic_torch_save(blob, self.out_dir / f"epoch_{self.epoch:03d}.pt")
        snapshots = sorted(self.out_dir.glob("epoch_*.pt"))
        for old in snapshots[: max(len(snapshots) - cfg.keep_snapshots, 0)]:
            old.unlink()
        if improved:
            meta = {
                "epoch": self.epoch,
                "val": val_record,
                "train_config": asdict(cfg),
                "fit_config": self.fit.to_dict(),
                "data": str(self.data),
            }
            atomic_torch_save(checkpoint_dict(self.net, meta), self.out_dir / FILES["sampler"])


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
    ``epochs`` (extending the run also stretches the tau_c schedule), ``threads``, ``device``,
    ``workers``, ``max_minutes`` and ``keep_snapshots`` of ``cfg`` apply. ``stop_after_epoch`` ends the
    run after that many completed epochs (as an interruption would). torch's thread count is set to
    ``cfg.threads`` for the run and restored afterwards.

    Launched by ``torchrun`` with ``WORLD_SIZE > 1``, this joins the process group for the duration of
    the call (``backend``: None = nccl on CUDA, gloo on CPU, or ``$CUBOIDS_DIST_BACKEND``) and trains data
    parallel as the module docstring describes; every rank must pass the same arguments. Only rank 0
    calls ``on_event`` and writes to ``out_dir``, which must be visible to every rank for ``resume``.
    The final record then adds ``world_size`` and ``param_sha256``, one hash of the final weights per
    rank, all equal when the replicas stayed in sync.
    """
    out_dir = Path(out_dir)
    fit = fit or FitConfig()
    state = None
    if resume is not None:
        state = _load_state(resume)
        keep = ("epochs", "threads", "device", "workers", "max_minutes", "keep_snapshots")
        cfg = replace(SamplerTrainConfig(**state["train_config"]), **{k: getattr(cfg, k) for k in keep})
        net_cfg = SamplerNetConfig.from_dict(state["config"])
        fit = FitConfig(**state["fit_config"])
    threads_before = torch.get_num_threads()
    torch.set_num_threads(cfg.threads)
    try:
        with distributed(cfg.device, backend) as ctx:
            if ctx.is_main:
                out_dir.mkdir(parents=True, exist_ok=True)
            emit = (on_event if ctx.is_main else None) or (lambda record: None)
            return _train(ctx, cfg, data, out_dir, net_cfg, fit, state, resume, emit, stop_after_epoch)
    finally:
        torch.set_num_threads(threads_before)


def _train(ctx, cfg, data, out_dir, net_cfg, fit, state, resume, emit, stop_after_epoch) -> dict:
    t_start = time.perf_counter()
    run = _Run(ctx, cfg, data, out_dir, net_cfg, fit, state, emit)
    resolved = {
        "train": asdict(cfg),
        "net": run.net_cfg.to_dict(),
        "fit": fit.to_dict(),
        "data": str(data),
        "split": run.split_note,
        "train_frames": len(run.scenes),
        "val_frames": len(run.val_frames),
        "resumed_from": None if resume is None else str(resume),
    }
    start = {
        "event": "start",
        "epoch": run.epoch,
        "epochs": cfg.epochs,
        "parameters": parameter_count(run.net),
        "train_frames": len(run.scenes),
        "val_frames": len(run.val_frames),
        "split": run.split_note,
    }
    if ctx.active:
        resolved["distributed"] = {"world_size": ctx.world_size, "backend": ctx.backend}
        start["world_size"] = ctx.world_size
    if ctx.is_main:
        atomic_write_json(out_dir / "config.json", resolved)
    run.log(start)
    if state is None and cfg.validate_initial:
        run.validate(initial=True)
    while run.epoch < cfg.epochs:
        t_epoch = time.perf_counter()
        summary = run.train_epoch()
        improved, val_record = run.validate()
        run.save(improved, val_record)
        run.log(
            {
                "event": "epoch",
                "epoch": run.epoch,
                **summary,
                "best": improved,
                "seconds": time.perf_counter() - t_epoch,
            }
        )
        if stop_after_epoch is not None and run.epoch >= stop_after_epoch:
            break
        if cfg.max_minutes is not None:
            # Rank 0's clock decides for every rank: ranks that disagree would deadlock in the next step.
            over = time.perf_counter() - t_start > 60.0 * cfg.max_minutes
            if ctx.broadcast_float(float(over)) > 0.5:
                run.log({"event": "stop", "epoch": run.epoch, "reason": "max_minutes"})
                break
    final = {
        "event": "end",
        "epochs_done": run.epoch,
        "best": run.best,
        "weights": str(out_dir / FILES["sampler"]),
        "last": str(out_dir / "last.pt"),
        "seconds": time.perf_counter() - t_start,
    }
    if ctx.active:
        final["world_size"] = ctx.world_size
        final["param_sha256"] = ctx.gather(state_sha256(run.net.state_dict()))
    run.log(final)
    # Rank 0 finishes its files before any rank tears the process group down.
    ctx.barrier()
    return final

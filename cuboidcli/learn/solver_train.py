"""Pre-training of the neural cuboid solver on synthetic minimal sets (paper appendix "Neural Cuboid Solver").

Loss: the mean squared point-to-surface distance d(h, y)^2 (Eq. 2) of each set's points to the predicted
cuboid, averaged over the batch; flagged outlier points are left out so that the net learns to fit the
box the other points lie on. Batches are generated on the fly, each from a seed derived from the run seed
and the iteration, so a run is reproducible and ``resume`` continues it exactly. Adam with a linear
warm-up and a cosine decay, gradient-norm clipping.

Files in ``out_dir``: ``config.json`` (resolved configs), ``log.jsonl`` (one record per log / validation
event), ``last.pt`` and ``step_XXXXXXX.pt`` (training state: weights, optimizer, RNG, iteration; the last
``keep_snapshots`` are kept) and ``best.pt`` (weights-only, the lowest validation residual so far; the same
file as ``solver_v2.pt`` too, the name ``--weights OUT`` reads). The loop is
:func:`cuboidcli.learn.trainer.run_job`'s (:class:`SolverJob`).
This module prints nothing: progress goes to the ``on_event`` callback.

Multi-process (``torchrun``, see :mod:`cuboidcli.learn.distributed`): every rank holds a replica wrapped in
DistributedDataParallel and draws its own ``batch`` sets per step (from a seed of run seed, iteration and
rank, :func:`batch_seed`), so the global batch is ``batch * world_size`` and the gradient is the mean over
it. The lr schedule counts optimizer steps, identical on every rank; ``lr`` is the rate for the global
batch and is not rescaled with the world size. Rank 0 alone validates and writes files; decisions taken
from its clock (the time budget) are broadcast so that all ranks change lr and stop at the same step.
"""

from __future__ import annotations

import itertools
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass
from pathlib import Path

import torch
from torch import Tensor

from cuboidcli.geometry.kernels import cuboid_sq_distance
from cuboidcli.io.checkpoints import read_checkpoint
from cuboidcli.learn.job import OneNetJob, StepResult, Validation
from cuboidcli.learn.run_config import RunConfig, RunFields, WarmupCosine
from cuboidcli.learn.trainer import Run, run_job
from cuboidcli.learn.training_state import resumed
from cuboidcli.nets.checkpoint import checkpoint_dict, parameter_count
from cuboidcli.nets.solver import SolverNet, SolverNetConfig
from cuboidcli.solvers.synthetic import SyntheticBatch, SyntheticConfig, seeded_batch
from cuboidcli.weights import FILES, default_path

STATE_KIND = "solver-train-state"
#: The best weights (lowest validation residual), a plain weights file; written under the name of the solver
#: in a weights folder (``solver_v2.pt``) as well.
BEST = "best.pt"
#: Seeds of the held-out validation sets live far from the training seeds (seed * 2^32 + iteration).
VAL_SEED = 2**62 + 2024
#: Rank r > 0 offsets its training seeds by r * RANK_SEED_STRIDE: rank 0 keeps the single-process stream,
#: and the ranks' streams cannot meet as long as seed < 2^16 and iterations < 2^32.
RANK_SEED_STRIDE = 2**48


@dataclass(frozen=True)
class SolverTrainConfig(WarmupCosine, RunFields):
    """Optimisation schedule and bookkeeping of a pre-training run; Adam follows the :class:`WarmupCosine`
    schedule."""

    iters: int = 50000
    """Optimizer steps (the paper: 150k at batch 4096 on a GPU)."""
    batch: int = 256
    """Minimal sets per step and process: a run on N processes takes batch * N sets per step."""
    lr: float = 3e-3
    """Peak Adam learning rate: warm-up, then cosine decay (the paper: 1e-4, constant)."""
    log_every: int = 50
    val_every: int = 1000
    """Validate and maybe write ``best.pt`` every so many steps (and at the end)."""
    ckpt_every: int = 1000
    keep_snapshots: int = 3
    val_sets: int = 4096
    """Sets in each held-out validation set (one clean, one with noise and outliers)."""


def set_sq_distances(points: Tensor, centers: Tensor, half_sizes: Tensor, rotations: Tensor) -> Tensor:
    """d(h_b, y)^2 of each set's own points to its own cuboid: points (B, C, 3) -> (B, C), m^2."""
    local = torch.einsum("bck,bkj->bcj", points - centers[:, None, :], rotations)
    return cuboid_sq_distance(local, half_sizes)


def masked_set_mean(values: Tensor, mask: Tensor) -> Tensor:
    """Mean of (B, C) values over each set's masked entries: (B,). Every set has at least one inlier."""
    m = mask.to(values.dtype)
    return (values * m).sum(1) / m.sum(1).clamp_min(1.0)


def solver_loss(net: SolverNet, points: Tensor, inlier: Tensor) -> Tensor:
    """l_solver of the paper over the inlier points, averaged over the batch: points (B, C, 3), inlier
    (B, C) -> scalar, m^2."""
    return masked_set_mean(set_sq_distances(points, *net(points)), inlier).mean()


def batch_seed(seed: int, it: int, rank: int = 0) -> int:
    """Seed of the training batch of step ``it`` (0-based) on ``rank``; rank 0 is the single-process one."""
    return seed * 2**32 + it + rank * RANK_SEED_STRIDE


def validation_sets(n: int, data: SyntheticConfig) -> dict[str, SyntheticBatch]:
    """The fixed held-out sets: ``clean`` (the paper's distribution) and ``noisy`` (noise + outliers)."""
    return {"clean": seeded_batch(n, data.clean(), VAL_SEED), "noisy": seeded_batch(n, data, VAL_SEED + 1)}


def evaluate_solver(solver: Callable, batch: SyntheticBatch) -> dict:
    """Residuals of a CuboidSolver on a batch, over the inlier points.

    ``msd_m2``: mean over sets of the set's mean squared distance (the training loss);
    ``mean_cm`` / ``median_cm``: mean and median point-to-surface distance, cm; ``seconds``: solver time.
    """
    start = time.perf_counter()
    centers, half_sizes, rotations = solver(batch.points)
    seconds = time.perf_counter() - start
    sq = set_sq_distances(batch.points, centers.float(), half_sizes.float(), rotations.float())
    dist_cm = sq[batch.inlier].sqrt() * 100.0
    return {
        "msd_m2": masked_set_mean(sq, batch.inlier).mean().item(),
        "mean_cm": dist_cm.mean().item(),
        "median_cm": dist_cm.median().item(),
        "seconds": seconds,
    }


def _net_solver(net: SolverNet) -> Callable:
    from cuboidcli.solvers.neural import NeuralSolver

    return NeuralSolver(net=net, device=next(net.parameters()).device)


class SolverJob(OneNetJob):
    """Pre-training of the neural solver as a job of :func:`~cuboidcli.learn.trainer.run_job`: step-based,
    one synthetic batch a step; rank 0 alone validates (on the fixed held-out sets)."""

    name = "solver"
    net_name = "solver"
    state_kind = STATE_KIND
    step_event = "train"
    end_event = "done"
    rate_key = "sets_per_s"
    lower_is_better = True

    def __init__(self, cfg: SolverTrainConfig, net_cfg: SolverNetConfig, data_cfg: SyntheticConfig):
        self.cfg, self.net_cfg, self.data_cfg = cfg, net_cfg, data_cfg

    def setup(self, run: Run, state: dict | None) -> None:
        ctx, device = run.ctx, run.device
        # Same seed on every rank (run_job seeded it), so the replicas start equal even before DDP
        # broadcasts rank 0's weights.
        self.net = SolverNet(self.net_cfg).to(device)
        if state is not None:
            self.net.load_state_dict(state["state_dict"])
        # ``model`` is what the loss calls: DDP all-reduces (averages) the gradients during backward, so
        # every rank clips and steps with the same gradient. Validation and checkpoints use the bare net.
        self.model = self.net
        if ctx.active:
            from torch.nn.parallel import DistributedDataParallel

            device_ids = [device.index] if device.type == "cuda" else None
            self.model = DistributedDataParallel(self.net, device_ids=device_ids)
        self.optimizer = torch.optim.Adam(self.net.parameters(), lr=self.cfg.lr_at(0, self.cfg.iters))
        # Only rank 0 validates; the others wait for it in the next collective.
        self.val = validation_sets(self.cfg.val_sets, self.data_cfg) if ctx.is_main else {}
        self.net.train()

    def batches(self, run: Run):
        return itertools.count(run.step)

    def step(self, run: Run, it: int) -> StepResult:
        cfg = self.cfg
        batch = seeded_batch(cfg.batch, self.data_cfg, batch_seed(cfg.seed, it, run.ctx.rank))
        points, inlier = batch.points.to(run.device), batch.inlier.to(run.device)
        lr = cfg.lr_at(it, cfg.iters, run.time_fraction())
        for group in self.optimizer.param_groups:
            group["lr"] = lr
        loss = solver_loss(self.model, points, inlier)
        self.optimizer.zero_grad(set_to_none=True)
        loss.backward()
        grad_norm = torch.nn.utils.clip_grad_norm_(self.net.parameters(), cfg.grad_clip)
        self.optimizer.step()
        # A collective: the loss of the global batch, on every rank
        loss_m2 = run.ctx.mean_float(loss.item())
        fields = {"iteration": it + 1, "lr": lr, "grad_norm": float(grad_norm)}
        return StepResult({"loss_m2": loss_m2}, fields, items=cfg.batch * run.ctx.world_size)

    def validate(self, run: Run) -> Validation | None:
        if not run.ctx.is_main:
            return None
        self.net.eval()
        self.metrics = {name: evaluate_solver(_net_solver(self.net), b) for name, b in self.val.items()}
        self.net.train()
        flat = {f"{k}_{m}": v for k, ms in self.metrics.items() for m, v in ms.items()}
        return Validation(self.metrics["noisy"]["msd_m2"], {"iteration": run.step, **flat})

    def more_state(self, run: Run) -> dict:
        return {"data_config": self.data_cfg.to_dict()}

    def best_weights(self, run: Run, validation: dict) -> dict[str, dict]:
        meta = {
            "iteration": run.step,
            "validation": self.metrics,
            "parameters": parameter_count(self.net),
            "train_config": asdict(self.cfg),
            "data_config": self.data_cfg.to_dict(),
        }
        weights = checkpoint_dict(self.net, meta)
        return {BEST: weights, FILES["solver"]: weights}

    def settings(self, run: Run) -> dict:
        return {"train": asdict(self.cfg), "net": self.net_cfg.to_dict(), "data": self.data_cfg.to_dict()}

    def start_fields(self, run: Run) -> dict:
        return {"iteration": run.step, "iters": self.cfg.iters}

    def end_fields(self, run: Run) -> dict:
        return {"iteration": run.step, "best_noisy_msd_m2": run.best, "best": str(run.out_dir / BEST)}


#: Fields of the caller's config that replace the checkpoint's when resuming.
RESUME_OVERRIDES = (
    "threads",
    "device",
    "max_minutes",
    "log_every",
    "val_every",
    "ckpt_every",
    "keep_snapshots",
)


def train_solver(
    cfg: SolverTrainConfig,
    net_cfg: SolverNetConfig,
    out_dir: str | Path,
    data_cfg: SyntheticConfig | None = None,
    resume: str | Path | None = None,
    on_event: Callable[[dict], None] | None = None,
    backend: str | None = None,
) -> dict:
    """Run (or resume) pre-training; returns the final record (iteration, best validation, paths).

    Exactly reproducible from ``cfg.seed`` (and the number of processes) unless a time budget
    (``max_minutes``) shapes the schedule.

    When resuming, the schedule, data and net shape come from the checkpoint; only the fields of ``cfg``
    in :data:`RESUME_OVERRIDES` (threads, device, time budget, logging and checkpoint intervals) apply.

    Launched by ``torchrun`` with ``WORLD_SIZE > 1``, this joins the process group for the duration of
    the call (``backend``: None = nccl on CUDA, gloo on CPU, or ``$CUBOIDS_DIST_BACKEND``); only rank 0
    calls ``on_event`` and writes to ``out_dir``, which must then be visible to every rank (resume reads
    it on all of them). The final record holds ``world_size`` and ``param_sha256``, one hash of the final
    weights per rank, all equal when the replicas stayed in sync.
    """
    hint = "last.pt or step_*.pt"
    state, cfg = resumed(resume, cfg, RESUME_OVERRIDES, STATE_KIND, "solver training", hint)
    if state is not None:
        net_cfg = SolverNetConfig.from_dict(state["config"])
        data_cfg = SyntheticConfig(**state["data_config"])
    run = RunConfig.of(
        cfg,
        out_dir,
        resume,
        max_steps=cfg.iters,
        minutes_span_resumes=True,
        save_every=cfg.ckpt_every,
        snapshot_name="step_{step:07d}.pt",
        backend=backend,
    )
    return run_job(SolverJob(cfg, net_cfg, data_cfg or SyntheticConfig()), run, state, on_event)


def median_seconds(solver: Callable, points: Tensor, repeats: int = 5) -> dict:
    """Median wall and process CPU time of ``solver(points)`` over ``repeats`` calls after a warm-up, s.

    On a shared machine the wall time depends on the load; CPU time summed over this process's threads
    is closer to what an idle machine would take on one core."""
    solver(points)
    wall, cpu = [], []
    for _ in range(repeats):
        start, start_cpu = time.perf_counter(), time.process_time()
        solver(points)
        wall.append(time.perf_counter() - start)
        cpu.append(time.process_time() - start_cpu)
    return {"wall_s": sorted(wall)[len(wall) // 2], "cpu_s": sorted(cpu)[len(cpu) // 2]}


def compare_on_validation(weights: str | Path | None = None, n_sets: int = 4096, repeats: int = 5) -> dict:
    """The model card's numbers: residuals of the neural solver (``weights``, None = shipped), the numerical
    solver (PCA + 50 Adam steps) and its PCA initial box on the held-out sets of the weights' training data,
    and the median time of each on ``n_sets`` sets with the current torch thread count."""
    from cuboidcli.solvers.neural import NeuralSolver
    from cuboidcli.solvers.numerical import NumericalSolver, pca_init

    path = Path(weights) if weights is not None else default_path("solver")
    neural = NeuralSolver(path)
    meta = read_checkpoint(path, "solver").get("meta", {})
    data = SyntheticConfig(**meta["data_config"]) if "data_config" in meta else SyntheticConfig()
    val = validation_sets(n_sets, data)
    solvers = {
        "neural": neural,
        "numerical": NumericalSolver(bounds=neural.bounds),
        "pca_box": lambda p: pca_init(p, neural.bounds),
    }
    report = {"weights": str(path), "sets": n_sets, "threads": torch.get_num_threads()}
    for name, solver in solvers.items():
        report[name] = {k: evaluate_solver(solver, batch) for k, batch in val.items()}
        report[name]["time_median"] = median_seconds(solver, val["noisy"].points, repeats)
    return report

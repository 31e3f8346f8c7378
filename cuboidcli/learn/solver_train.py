"""Pre-training of the neural cuboid solver on synthetic minimal sets (paper appendix "Neural Cuboid Solver").

Loss: the mean squared point-to-surface distance d(h, y)^2 (Eq. 2) of each set's points to the predicted
cuboid, averaged over the batch; flagged outlier points are left out so that the net learns to fit the
box the other points lie on. Batches are generated on the fly, each from a seed derived from the run seed
and the iteration, so a run is reproducible and ``resume`` continues it exactly. Adam with a linear
warm-up and a cosine decay, gradient-norm clipping.

Files in ``out_dir``: ``config.json`` (resolved configs), ``log.jsonl`` (one record per log / validation
event), ``last.pt`` and ``step_XXXXXXX.pt`` (training state: weights, optimizer, RNG, iteration; the last
``keep_snapshots`` are kept) and ``best.pt`` (weights-only, the lowest validation residual so far).
This module prints nothing: progress goes to the ``on_event`` callback.

Multi-process (``torchrun``, see :mod:`cuboidcli.learn.distributed`): every rank holds a replica wrapped in
DistributedDataParallel and draws its own ``batch`` sets per step (from a seed of run seed, iteration and
rank, :func:`batch_seed`), so the global batch is ``batch * world_size`` and the gradient is the mean over
it. The lr schedule counts optimizer steps, identical on every rank; ``lr`` is the rate for the global
batch and is not rescaled with the world size. Rank 0 alone validates and writes files; decisions taken
from its clock (the time budget) are broadcast so that all ranks change lr and stop at the same step.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import torch
from torch import Tensor

from cuboidcli.geometry.kernels import cuboid_sq_distance
from cuboidcli.io.atomic import atomic_torch_save, atomic_write_json
from cuboidcli.io.checkpoints import read_checkpoint
from cuboidcli.learn.distributed import DistContext, distributed, state_sha256
from cuboidcli.nets.checkpoint import checkpoint_dict, parameter_count
from cuboidcli.nets.solver import SolverNet, SolverNetConfig
from cuboidcli.solvers.synthetic import SyntheticBatch, SyntheticConfig, seeded_batch
from cuboidcli.weights import default_path

#: Seeds of the held-out validation sets live far from the training seeds (seed * 2^32 + iteration).
VAL_SEED = 2**62 + 2024
#: Rank r > 0 offsets its training seeds by r * RANK_SEED_STRIDE: rank 0 keeps the single-process stream,
#: and the ranks' streams cannot meet as long as seed < 2^16 and iterations < 2^32.
RANK_SEED_STRIDE = 2**48


@dataclass(frozen=True)
class SolverTrainConfig:
    """Optimisation schedule and bookkeeping of a pre-training run."""

    iters: int = 50000
    """Optimizer steps (the paper: 150k at batch 4096 on a GPU)."""
    batch: int = 256
    """Minimal sets per step and process: a run on N processes takes batch * N sets per step."""
    lr: float = 3e-3
    """Peak Adam learning rate (the paper: 1e-4, constant)."""
    warmup: int = 500
    """Linear warm-up steps from lr / warmup to lr."""
    final_lr_ratio: float = 0.02
    """The cosine decay ends at lr * final_lr_ratio."""
    grad_clip: float = 1.0
    """Max global gradient norm."""
    seed: int = 0
    """Seeds the initial weights and every training batch."""
    threads: int = 1
    """torch CPU threads (the machine's cores are shared)."""
    device: str = "cpu"
    log_every: int = 50
    val_every: int = 1000
    """Validate and maybe write ``best.pt`` every so many steps (and at the end)."""
    ckpt_every: int = 1000
    keep_snapshots: int = 3
    val_sets: int = 4096
    """Sets in each held-out validation set (one clean, one with noise and outliers)."""
    max_minutes: float | None = None
    """Time budget, minutes of training wall time summed over resumed sessions. The cosine decay then
    follows whichever budget is used up faster, steps or time, and the run ends when either is spent
    (with a validation and a checkpoint). Such a run depends on the machine's speed: not bit-exact."""


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


def lr_at(it: int, cfg: SolverTrainConfig, time_fraction: float = 0.0) -> float:
    """Learning rate of step ``it`` (0-based): linear warm-up, then cosine down to final_lr_ratio * lr.

    ``time_fraction``: share of the time budget used so far; the decay follows it when it runs ahead.
    """
    if it < cfg.warmup:
        return cfg.lr * (it + 1) / cfg.warmup
    span = max(1, cfg.iters - cfg.warmup)
    progress = min(1.0, max((it - cfg.warmup) / span, time_fraction))
    cosine = 0.5 * (1.0 + math.cos(math.pi * progress))
    return cfg.lr * (cfg.final_lr_ratio + (1.0 - cfg.final_lr_ratio) * cosine)


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


def _train_state(
    net, opt, it: int, best: float, elapsed_s: float, cfg, net_cfg, data_cfg, world: int
) -> dict:
    return {
        "kind": "solver-train-state",
        "config": net_cfg.to_dict(),
        "state_dict": net.state_dict(),
        "optimizer": opt.state_dict(),
        "rng": torch.get_rng_state(),
        "iteration": it,
        "best_msd_m2": best,
        "elapsed_s": elapsed_s,
        "train_config": asdict(cfg),
        "data_config": data_cfg.to_dict(),
        "world_size": world,
    }


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

    When resuming, the schedule, data and net shape come from the checkpoint; only ``threads``,
    ``device``, ``max_minutes`` and the logging intervals of ``cfg`` apply.

    Launched by ``torchrun`` with ``WORLD_SIZE > 1``, this joins the process group for the duration of
    the call (``backend``: None = nccl on CUDA, gloo on CPU, or ``$CUBOIDS_DIST_BACKEND``); only rank 0
    calls ``on_event`` and writes to ``out_dir``, which must then be visible to every rank (resume reads
    it on all of them). The final record adds ``world_size`` and ``param_sha256``, one hash of the final
    weights per rank, all equal when the replicas stayed in sync.
    """
    with distributed(cfg.device, backend) as ctx:
        return _train(ctx, cfg, net_cfg, Path(out_dir), data_cfg, resume, on_event)


def _train(
    ctx: DistContext,
    cfg: SolverTrainConfig,
    net_cfg: SolverNetConfig,
    out_dir: Path,
    data_cfg: SyntheticConfig | None,
    resume: str | Path | None,
    on_event: Callable[[dict], None] | None,
) -> dict:
    if ctx.is_main:
        out_dir.mkdir(parents=True, exist_ok=True)
    emit = (on_event if ctx.is_main else None) or (lambda record: None)
    state = None
    if resume is not None:
        state = read_checkpoint(resume)
        if state.get("kind") != "solver-train-state":
            raise ValueError(f"{resume} is not a training checkpoint (use last.pt or step_*.pt)")
        keep = ("threads", "device", "max_minutes", "log_every", "val_every", "ckpt_every", "keep_snapshots")
        cfg = replace(SolverTrainConfig(**state["train_config"]), **{k: getattr(cfg, k) for k in keep})
        net_cfg = SolverNetConfig.from_dict(state["config"])
        data_cfg = SyntheticConfig(**state["data_config"])
    data_cfg = data_cfg or SyntheticConfig()
    torch.set_num_threads(cfg.threads)
    device = torch.device(cfg.device)
    if ctx.active and device.type == "cuda":
        device = torch.device("cuda", ctx.local_rank)  # one GPU per process on the node

    # Same seed on every rank, so the replicas start equal even before DDP broadcasts rank 0's weights.
    torch.manual_seed(cfg.seed)
    net = SolverNet(net_cfg).to(device)
    # ``model`` is what the loss calls: DDP all-reduces (averages) the gradients during backward, so every
    # rank clips and steps with the same gradient. Validation and checkpoints use the bare ``net``.
    model = net
    if ctx.active:
        from torch.nn.parallel import DistributedDataParallel

        model = DistributedDataParallel(net, device_ids=[device.index] if device.type == "cuda" else None)
    opt = torch.optim.Adam(net.parameters(), lr=lr_at(0, cfg))
    start, best, spent_s = 0, math.inf, 0.0
    if state is not None:
        net.load_state_dict(state["state_dict"])
        opt.load_state_dict(state["optimizer"])
        # The global RNG draws nothing during training (batches come from seeded generators of their own,
        # the net has no dropout), so rank 0's saved state serves every rank.
        torch.set_rng_state(state["rng"])
        start, best, spent_s = int(state["iteration"]), float(state["best_msd_m2"]), float(state["elapsed_s"])
    resolved = {"train": asdict(cfg), "net": net_cfg.to_dict(), "data": data_cfg.to_dict()}
    resolved["resumed_from"] = None if resume is None else str(resume)
    if ctx.active:
        resolved["distributed"] = {"world_size": ctx.world_size, "backend": ctx.backend}
    if ctx.is_main:
        atomic_write_json(out_dir / "config.json", resolved)
    # Only rank 0 validates; the others wait for it in the next gradient all-reduce.
    val = validation_sets(cfg.val_sets, data_cfg) if ctx.is_main else {}
    log_path = out_dir / "log.jsonl"
    n_params = parameter_count(net)
    emit(
        {
            "event": "start",
            "iteration": start,
            "iters": cfg.iters,
            "parameters": n_params,
            "world_size": ctx.world_size,
        }
    )

    def log(record: dict) -> None:
        if not ctx.is_main:
            return
        with log_path.open("a", encoding="utf-8") as f:
            f.write(json.dumps(record) + "\n")
        emit(record)

    def validate(it: int) -> dict:
        net.eval()
        metrics = {name: evaluate_solver(_net_solver(net), batch) for name, batch in val.items()}
        net.train()
        return metrics

    def elapsed() -> float:
        return spent_s + time.perf_counter() - t0

    def time_fraction() -> float:
        if cfg.max_minutes is None:
            return 0.0
        # Rank 0's clock rules: the lr and the stop decision derive from it and must agree on all ranks.
        return ctx.broadcast_float(elapsed() / (60.0 * cfg.max_minutes))

    def save_state(it: int) -> None:
        if not ctx.is_main:
            return
        blob = _train_state(net, opt, it, best, elapsed(), cfg, net_cfg, data_cfg, ctx.world_size)
        atomic_torch_save(blob, out_dir / f"step_{it:07d}.pt")
        atomic_torch_save(blob, out_dir / "last.pt")
        for old in sorted(out_dir.glob("step_*.pt"))[: -cfg.keep_snapshots]:
            old.unlink(missing_ok=True)

    t0 = time.perf_counter()
    window_t, window_loss, window_n = time.perf_counter(), 0.0, 0
    it = start
    net.train()
    while it < cfg.iters:
        batch = seeded_batch(cfg.batch, data_cfg, batch_seed(cfg.seed, it, ctx.rank))
        points, inlier = batch.points.to(device), batch.inlier.to(device)
        for group in opt.param_groups:
            group["lr"] = lr = lr_at(it, cfg, time_fraction())
        loss = solver_loss(model, points, inlier)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        grad_norm = torch.nn.utils.clip_grad_norm_(net.parameters(), cfg.grad_clip)
        opt.step()
        it += 1
        window_loss += loss.item()
        window_n += 1
        timed_out = time_fraction() >= 1.0
        last = it == cfg.iters or timed_out
        if it % cfg.log_every == 0 or last:
            now = time.perf_counter()
            log(
                {
                    "event": "train",
                    "iteration": it,
                    # A collective: every rank logs at the same steps, so all of them get here.
                    "loss_m2": ctx.mean_float(window_loss / window_n),
                    "lr": lr,
                    "grad_norm": float(grad_norm),
                    "sets_per_s": window_n * cfg.batch * ctx.world_size / max(now - window_t, 1e-9),
                    "elapsed_s": elapsed(),
                }
            )
            window_t, window_loss, window_n = now, 0.0, 0
        if ctx.is_main and (it % cfg.val_every == 0 or last):
            metrics = validate(it)
            improved = metrics["noisy"]["msd_m2"] < best
            if improved:
                best = metrics["noisy"]["msd_m2"]
                meta = {
                    "iteration": it,
                    "validation": metrics,
                    "parameters": n_params,
                    "train_config": asdict(cfg),
                    "data_config": data_cfg.to_dict(),
                }
                atomic_torch_save(checkpoint_dict(net, meta), out_dir / "best.pt")
            log(
                {
                    "event": "val",
                    "iteration": it,
                    "best": improved,
                    "elapsed_s": elapsed(),
                    **{f"{k}_{m}": v for k, ms in metrics.items() for m, v in ms.items()},
                }
            )
            window_t = time.perf_counter()  # keep validation time out of the throughput
        if it % cfg.ckpt_every == 0 or last:
            save_state(it)
        if timed_out:
            break
    final = {
        "event": "done",
        "iteration": it,
        "best_noisy_msd_m2": best,
        "timed_out": it < cfg.iters,
        "elapsed_s": elapsed(),
        "best": str(out_dir / "best.pt"),
        "last": str(out_dir / "last.pt"),
        "world_size": ctx.world_size,
        "param_sha256": ctx.gather(state_sha256(net.state_dict())),
    }
    log(final)
    # Rank 0 finishes its files before any rank tears the process group down.
    ctx.barrier()
    return final


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

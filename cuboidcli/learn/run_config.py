"""Where and how long a training run goes (:class:`RunConfig`), the fields of a trainer's config it takes
over (:class:`RunFields`) and the trainers' learning-rate schedule (:class:`WarmupCosine`); the loop that
follows them is :func:`cuboidcli.learn.trainer.run_job`."""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, fields
from pathlib import Path


@dataclass(frozen=True)
class RunConfig:
    """Where a run writes, how long it runs and how often it logs, validates and saves."""

    out_dir: Path
    seed: int = 0
    """Seeds torch's global RNG before :meth:`~cuboidcli.learn.job.TrainingJob.setup` (the networks'
    initial weights)."""
    max_epochs: int | None = None
    """Epoch-based run: the job's :meth:`~cuboidcli.learn.job.TrainingJob.batches` are one epoch;
    validation and ``last.pt`` after each."""
    max_steps: int | None = None
    """Step-based run (``max_epochs`` None): steps in all; validation and saves every N steps."""
    max_minutes: float | None = None
    stop_within_epoch: bool = False
    """Check the time limit after every step (always so in a step-based run), else after every epoch."""
    minutes_span_resumes: bool = False
    """``max_minutes`` counts the time of all sessions of a resumed run, else of this session."""
    log_every: int | None = 1
    """A step record every N steps (None: none)."""
    val_every: int | None = None
    """Step-based runs: validate every N steps (None: only at the last step)."""
    save_every: int | None = None
    """Step-based runs: ``last.pt`` (and a snapshot) every N steps (None: only at the last step)."""
    keep_snapshots: int = 0
    """Snapshots of the training state kept besides ``last.pt`` (0: none written)."""
    snapshot_name: str = "epoch_{epoch:03d}.pt"
    """File name of a snapshot, formatted with ``epoch`` and ``step``."""
    validate_initial: bool = False
    """Validate before the first step of a fresh run (a reference point; a candidate for the best weights
    when the job says so, :attr:`~cuboidcli.learn.job.TrainingJob.initial_is_candidate`)."""
    stop_after_epochs: int | None = None
    """End after this many epochs in all, as an interruption would (tests)."""
    resume: Path | None = None
    """The state the run continued from (for ``config.json``; :func:`~cuboidcli.learn.trainer.run_job`
    reads it if not given)."""
    threads: int | None = 1
    """torch's CPU threads during the run (None: as they are)."""
    device: str = "cpu"
    """torch device; under torchrun ``cuda`` becomes the rank's GPU (``cuda:LOCAL_RANK``)."""
    backend: str | None = None
    """Process-group backend under torchrun (None: nccl on CUDA, gloo on the CPU)."""

    def __post_init__(self) -> None:
        if (self.max_epochs is None) == (self.max_steps is None):
            raise ValueError("a run is either epoch-based (max_epochs) or step-based (max_steps)")
        for name in ("log_every", "val_every", "save_every"):
            value = getattr(self, name)
            if value is not None and value < 1:
                raise ValueError(f"{name} must be at least 1, got {value}")
        if self.keep_snapshots < 0:
            raise ValueError(f"keep_snapshots must not be negative, got {self.keep_snapshots}")

    @classmethod
    def of(cls, cfg: object, out_dir: str | Path, resume: str | Path | None = None, **settings) -> RunConfig:
        """The run of a trainer's config dataclass ``cfg``: every field of this class that ``cfg`` has a
        field of the same name for (``seed``, ``max_minutes``, ``threads``, ``device``, ...) takes
        ``cfg``'s value; ``settings`` set the others (``max_epochs=cfg.epochs``) or replace those."""
        own = {f.name for f in fields(cls)} - {"out_dir", "resume"}
        taken = {f.name: getattr(cfg, f.name) for f in fields(cfg) if f.name in own}
        resume = None if resume is None else Path(resume)
        return cls(Path(out_dir), resume=resume, **{**taken, **settings})

    @property
    def step_based(self) -> bool:
        return self.max_epochs is None

    def snapshot_glob(self) -> str:
        """The snapshots' file names as a glob pattern (``epoch_*.pt``)."""
        return re.sub(r"\{[^}]*\}", "*", self.snapshot_name)


@dataclass(frozen=True)
class RunFields:
    """The fields of a trainer's config that :meth:`RunConfig.of` takes over into its run: the seed, where
    the steps run and the time budget. A config redeclares a field to give it another default."""

    seed: int = 0
    """Seeds the initial weights (of a network trained from scratch) and every random draw of the run: the
    order of the data, the batches, augmentation, hypotheses."""
    threads: int = 1
    """torch CPU threads (the machine's cores are shared)."""
    device: str = "cpu"
    """torch device of the training steps."""
    max_minutes: float | None = None
    """Time budget, minutes of training wall time; the run then ends with a validation and a checkpoint.
    Solver and depth training sum the sessions of a resumed run and their cosine decay follows the budget
    when it runs ahead (not bit-exact then); sampler training and fine-tuning count this session and stop
    after the epoch in which it ran out."""


@dataclass(frozen=True)
class WarmupCosine:
    """The learning-rate schedule of a trainer's config: a linear warm-up to ``lr``, then a cosine decay to
    ``lr * final_lr_ratio``, with the gradients clipped to a global norm. A config redeclares a field to
    give it another default."""

    lr: float = 1e-3
    """Peak learning rate: warm-up, then cosine decay."""
    warmup: int = 500
    """Linear warm-up steps from lr / warmup to lr."""
    final_lr_ratio: float = 0.02
    """The cosine decay ends at lr * final_lr_ratio."""
    grad_clip: float = 1.0
    """Max global gradient norm."""

    def lr_at(self, step: int, total: int, time_fraction: float = 0.0) -> float:
        """The learning rate of step ``step`` (0-based) of ``total``: the warm-up over ``warmup`` steps,
        then the cosine decay, which follows the time budget (``time_fraction``, the share used) when that
        runs out first."""
        if step < self.warmup:
            return self.lr * (step + 1) / self.warmup
        progress = min(1.0, max((step - self.warmup) / max(1, total - self.warmup), time_fraction))
        ratio = self.final_lr_ratio
        return self.lr * (ratio + (1.0 - ratio) * 0.5 * (1.0 + math.cos(math.pi * progress)))

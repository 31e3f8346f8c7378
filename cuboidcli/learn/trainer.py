"""The one training loop of the package: every trainer is a :class:`TrainingJob` run by :func:`run_job`.

A job says what is particular to it: its data, networks and optimizer (:meth:`~TrainingJob.setup`), one
optimizer step (:meth:`~TrainingJob.step`, on the items :meth:`~TrainingJob.batches` yields), validation
(:meth:`~TrainingJob.validate`) and what it adds to the training state (:meth:`~TrainingJob.state`); a
job that trains one network derives from :class:`OneNetJob` (both: :mod:`cuboidcli.learn.job`). A
:class:`RunConfig` says where and how long (the trainers' configs share the fields it takes over,
:class:`RunFields`, and their learning-rate schedule, :class:`WarmupCosine`; all three:
:mod:`cuboidcli.learn.run_config`); :mod:`cuboidcli.learn.training_state` reads the training state it
saves. The trainers import these names from here. The loop does the rest, the same way for every job:

- **Processes.** It joins the ``torchrun`` process group for the run (:mod:`cuboidcli.learn.distributed`)
  and sets torch's thread count, restoring it afterwards. Every rank runs the job's steps and validations
  (which may be collectives); rank 0 alone writes files and reports. Before the first step the ranks check
  that they hold the same weights and data (:meth:`TrainingJob.agreement`).
- **Files in** ``out_dir``: ``config.json`` (the job's resolved settings), ``log.jsonl`` (one JSON record
  a line: ``start``, the job's step records every ``log_every`` steps, ``val``, ``epoch``, ``stop`` and
  the final record), ``last.pt`` (the training state), snapshots of it (``snapshot_name``, the last
  ``keep_snapshots`` kept) and the best weights (the job's files, in the one weights format of
  :func:`cuboidcli.nets.checkpoint.checkpoint_dict`).
- **Resume.** ``last.pt`` (or a snapshot) holds the step and epoch count, the best validation value, the
  time spent, torch's global RNG and the optimizer's state besides the job's own entries; a resumed run
  continues from there (:func:`read_state` reads the states the trainers wrote before this loop existed).
- **Schedule.** An epoch-based run (``max_epochs``) validates and saves at the end of every epoch; a
  step-based run (``max_steps``) every ``val_every`` / ``save_every`` steps and at its last step.
- **Time limit.** ``max_minutes`` of wall time, measured from the start of the run (of this session, or
  of all sessions with ``minutes_span_resumes``), checked after every step or after every epoch
  (``stop_within_epoch``). Rank 0's clock decides and the decision is broadcast: ranks that disagreed
  would deadlock in the next all-reduce. The run then ends as after its last step (validation and
  ``last.pt``) and logs a ``stop`` record.
- **Best by validation.** The job's validation returns one value (higher is better, or lower with
  ``lower_is_better``); when it beats the best so far the job's weights files are written. A job without
  validation data returns None: the latest weights then count as the best.
"""

from __future__ import annotations

import json
import math
import time
from collections.abc import Callable, Iterable, Iterator
from pathlib import Path

import numpy as np
import torch

from cuboidcli.io.atomic import atomic_torch_save, atomic_write_json
from cuboidcli.learn.distributed import DistContext, distributed, launched_world_size
from cuboidcli.learn.job import StepResult, TrainingJob
from cuboidcli.learn.run_config import RunConfig
from cuboidcli.learn.training_state import LAST, params_sha256, read_state
from cuboidcli.nets.checkpoint import parameter_count

#: The loop's clock (tests replace it).
_clock = time.perf_counter


def _mean(records: list[dict[str, float]]) -> dict[str, float]:
    return {k: float(np.mean([r[k] for r in records])) for k in records[0]} if records else {}


class Run:
    """One run of a job: the loop's counters and clock, and what a job asks of the loop (:attr:`ctx`,
    :attr:`device`, :meth:`log`, :meth:`time_fraction`)."""

    def __init__(self, cfg: RunConfig, ctx: DistContext, job: TrainingJob, emit: Callable[[dict], None]):
        self.cfg, self.ctx, self.job, self._emit = cfg, ctx, job, emit
        self.out_dir = Path(cfg.out_dir)
        self.device = torch.device(cfg.device)
        if ctx.active and self.device.type == "cuda":
            self.device = torch.device("cuda", ctx.local_rank)  # one GPU per process on the node
        self.epoch = 0
        """Epochs done."""
        self.step = 0
        """Optimizer steps done."""
        self.best = math.inf if job.lower_is_better else -math.inf
        """The best validation value so far."""
        self.timed_out = False
        self._spent_s = 0.0  # in the sessions before this one
        self._t0 = _clock()

    # --- what jobs use ---------------------------------------------------------------------------------

    def seconds(self) -> float:
        """Wall time of this session."""
        return _clock() - self._t0

    def elapsed(self) -> float:
        """Wall time of the run, all sessions."""
        return self._spent_s + self.seconds()

    def time_fraction(self) -> float:
        """Share of ``max_minutes`` used (0 without a limit), rank 0's on every rank (a collective then)."""
        if self.cfg.max_minutes is None:
            return 0.0
        used = self.elapsed() if self.cfg.minutes_span_resumes else self.seconds()
        return self.ctx.broadcast_float(used / (60.0 * self.cfg.max_minutes))

    def emit(self, record: dict) -> None:
        """Report ``record`` (rank 0) without logging it."""
        if self.ctx.is_main:
            self._emit(record)

    def log(self, record: dict) -> None:
        """Append ``record`` to ``log.jsonl`` and report it (rank 0)."""
        if not self.ctx.is_main:
            return
        with (self.out_dir / "log.jsonl").open("a", encoding="utf-8") as f:
            f.write(json.dumps(record) + "\n")
        self._emit(record)

    # --- the loop ----------------------------------------------------------------------------------------

    def train(self, state: dict | None) -> dict:
        cfg, ctx, job = self.cfg, self.ctx, self.job
        torch.manual_seed(cfg.seed)
        if state is not None:
            self.epoch, self.step = int(state.get("epoch", 0)), int(state.get("step", 0))
            self.best = float(state.get("best", self.best))
            self._spent_s = float(state.get("elapsed_s", 0.0))
        job.setup(self, state)
        if state is not None:
            if job.optimizer is not None and "optimizer" in state:
                job.optimizer.load_state_dict(state["optimizer"])
            if "torch_rng" in state:
                # Jobs draw their data and samples from seeded generators of their own: rank 0's global
                # RNG serves every rank.
                torch.set_rng_state(state["torch_rng"])
        if ctx.active:
            # Ranks that differ here would train replicas that silently drift apart.
            mine = (params_sha256(job.networks()), job.agreement())
            if any(other != mine for other in ctx.gather(mine)):
                raise ValueError(
                    "the processes disagree on the training data or the networks' weights: every rank must "
                    "read the same dataset folder, starting weights (and --resume checkpoint)"
                )
        if ctx.is_main:
            settings = {**job.settings(self), "resumed_from": None if cfg.resume is None else str(cfg.resume)}
            if ctx.active:
                settings["distributed"] = {"world_size": ctx.world_size, "backend": ctx.backend}
            atomic_write_json(self.out_dir / "config.json", settings)
        self.log(self._start_record())
        if state is None and cfg.validate_initial:
            self._validate(initial=True)
        while self._more():
            if self._epoch():
                break
        return self._end()

    def _start_record(self) -> dict:
        counts = {k: parameter_count(m) for k, m in self.job.networks().items()}
        record = {"event": "start", "epoch": self.epoch, "step": self.step}
        if self.cfg.step_based:
            record["steps"] = self.cfg.max_steps
        else:
            record["epochs"] = self.cfg.max_epochs
        record["parameters"] = next(iter(counts.values())) if len(counts) == 1 else counts
        record["world_size"] = self.ctx.world_size
        return {**record, **self.job.start_fields(self)}

    def _more(self) -> bool:
        if self.cfg.step_based:
            return self.step < self.cfg.max_steps
        return self.epoch < self.cfg.max_epochs

    def _epoch(self) -> bool:
        """Run one epoch (a step-based run: up to its end); True when the run ends early."""
        cfg, job = self.cfg, self.job
        t_epoch = _clock()
        epoch_metrics: list[dict[str, float]] = []
        window: list[StepResult] = []
        window_t = _clock()
        steps_before = self.step
        for batch in job.batches(self):
            result = job.step(self, batch)
            self.step += 1
            epoch_metrics.append(result.metrics)
            window.append(result)
            if (cfg.step_based or cfg.stop_within_epoch) and self.time_fraction() >= 1.0:
                self.timed_out = True
            last = self.timed_out or (cfg.step_based and self.step >= cfg.max_steps)
            if cfg.log_every and (self.step % cfg.log_every == 0 or (cfg.step_based and last)):
                self.log(self._step_record(window, _clock() - window_t))
                window, window_t = [], _clock()
            if cfg.step_based:
                validate = last or self.step % (cfg.val_every or math.inf) == 0
                save = last or self.step % (cfg.save_every or math.inf) == 0
                if validate:
                    self._validate()
                if save:
                    self._save()
                if validate or save:
                    window_t = _clock()  # keep validation and saving out of the rate
            if last:
                break
        if cfg.step_based:
            if self.step == steps_before:
                raise RuntimeError(f"{job.name}: the job yielded no batch")
            return self._stopped()
        self.epoch += 1
        improved = self._validate()
        self._save()
        summary = _mean(epoch_metrics)
        seconds = _clock() - t_epoch
        self.log({"event": "epoch", "epoch": self.epoch, **summary, "best": improved, "seconds": seconds})
        if cfg.stop_after_epochs is not None and self.epoch >= cfg.stop_after_epochs:
            return True
        if not cfg.stop_within_epoch and self.time_fraction() >= 1.0:
            self.timed_out = True
        return self._stopped()

    def _stopped(self) -> bool:
        if self.timed_out:
            self.log({"event": "stop", "epoch": self.epoch, "step": self.step, "reason": "max_minutes"})
        return self.timed_out

    def _step_record(self, window: list[StepResult], seconds: float) -> dict:
        job = self.job
        record = {"event": job.step_event, **window[-1].fields, "step": self.step}
        record.update(_mean([r.metrics for r in window]))
        record["seconds"] = seconds
        if job.rate_key:
            record[job.rate_key] = sum(r.items for r in window) / max(seconds, 1e-9)
        record["elapsed_s"] = self.elapsed()
        return record

    def _better(self, value: float) -> bool:
        return value < self.best if self.job.lower_is_better else value > self.best

    def _validate(self, initial: bool = False) -> bool:
        """Validate, log and write the best weights when they improved; returns whether they did."""
        job = self.job
        validation = job.validate(self)
        if validation is None:
            improved, record = not initial, {}
        else:
            improved = (not initial or job.initial_is_candidate) and self._better(validation.value)
            if improved:
                self.best = validation.value
            record = validation.record
            tag = {"initial": True} if initial else {"best": improved}
            position = {"event": "val", "epoch": self.epoch, "step": self.step}
            self.log({**position, **tag, **record, "elapsed_s": self.elapsed()})
        if improved and self.ctx.is_main:
            for name, weights in job.best_weights(self, record).items():
                atomic_torch_save(weights, self.out_dir / name)
        return improved

    def _save(self) -> None:
        """The training state to ``last.pt`` and a snapshot; a collective (the job's state may gather)."""
        cfg, job = self.cfg, self.job
        blob = {"kind": job.state_kind, **job.state(self)}
        if not self.ctx.is_main:
            return
        blob.update(
            epoch=self.epoch,
            step=self.step,
            best=self.best,
            elapsed_s=self.elapsed(),
            world_size=self.ctx.world_size,
            torch_rng=torch.get_rng_state(),
        )
        if job.optimizer is not None:
            blob["optimizer"] = job.optimizer.state_dict()
        atomic_torch_save(blob, self.out_dir / LAST)
        if cfg.keep_snapshots:
            atomic_torch_save(blob, self.out_dir / cfg.snapshot_name.format(epoch=self.epoch, step=self.step))
            snapshots = sorted(self.out_dir.glob(cfg.snapshot_glob()))
            for old in snapshots[: max(len(snapshots) - cfg.keep_snapshots, 0)]:
                old.unlink(missing_ok=True)

    def _end(self) -> dict:
        final = {
            "event": self.job.end_event,
            "epoch": self.epoch,
            "step": self.step,
            "timed_out": self.timed_out,
            "seconds": self.seconds(),
            "elapsed_s": self.elapsed(),
            "out": str(self.out_dir),
            "last": str(self.out_dir / LAST),
            "world_size": self.ctx.world_size,
            # a collective: one hash of the final weights per rank, all equal when the replicas kept in step
            "param_sha256": self.ctx.gather(params_sha256(self.job.networks())),
        }
        final.update(self.job.end_fields(self))
        self.log(final)
        # Rank 0 finishes its files before any rank tears the process group down.
        self.ctx.barrier()
        return final


def run_job(
    job: TrainingJob,
    cfg: RunConfig,
    state: dict | None = None,
    on_event: Callable[[dict], None] | None = None,
) -> dict:
    """Run ``job`` under ``cfg`` (see the module docstring); returns the final record.

    ``state``: the training state to continue from (as :func:`read_state` returns it; None: read
    ``cfg.resume`` if set, else a fresh run). Launched by ``torchrun`` with ``WORLD_SIZE > 1`` this joins
    the process group for the duration of the call; every rank must pass the same arguments, and only rank
    0 calls ``on_event`` and writes to ``cfg.out_dir`` (which must be visible to every rank for resuming).
    """
    if launched_world_size() > 1 and not job.distributed:
        raise ValueError(f"cuboids train {job.name} runs in one process: start it without torchrun")
    if state is None and cfg.resume is not None:
        state = read_state(cfg.resume, job.state_kind, f"{job.name} training")
    threads_before = torch.get_num_threads()
    torch.set_num_threads(cfg.threads or threads_before)
    try:
        with distributed(cfg.device, cfg.backend) as ctx:
            if ctx.is_main:
                Path(cfg.out_dir).mkdir(parents=True, exist_ok=True)
            return Run(cfg, ctx, job, on_event or (lambda record: None)).train(state)
    finally:
        torch.set_num_threads(threads_before)


def shared_batch_step(
    ctx: DistContext,
    optimizer: torch.optim.Optimizer,
    params: Iterable[torch.Tensor],
    batch: list[int],
    one: Callable[[int], list[dict[str, float]]],
) -> dict[str, float]:
    """One optimizer step on the items of a global ``batch`` split over the ranks: this rank runs
    ``one(item)`` (forward and backward, each scaled to its share of the global batch, returning records
    of floats) on its share (:meth:`~DistContext.share`; it may have none), the gradients are summed over
    the ranks (one all-reduce, not DistributedDataParallel: the networks run several times per item) and
    every rank steps with the same gradient. Returns the mean of all ranks' records."""
    optimizer.zero_grad(set_to_none=True)
    records = []
    for item in ctx.share(batch):
        records += one(item)
    ctx.sum_gradients(params)
    optimizer.step()
    return _mean([r for shard in ctx.gather(records) for r in shard])  # in item order per rank


def batched(order: list[int], batch: int) -> Iterator[list[int]]:
    """``order`` in consecutive chunks of ``batch`` (the last one may be shorter)."""
    for b in range(0, len(order), batch):
        yield order[b : b + batch]

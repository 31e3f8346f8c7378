"""What a kind of training says to the loop of :func:`cuboidcli.learn.trainer.run_job`: a
:class:`TrainingJob` (one that trains a single network: :class:`OneNetJob`) and what its steps and
validations return (:class:`StepResult`, :class:`Validation`)."""

from __future__ import annotations

from abc import ABC, abstractmethod
from collections.abc import Iterable
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import ClassVar, Protocol

import torch

from cuboidcli.learn.distributed import DistContext
from cuboidcli.nets.checkpoint import NetConfig


class RunView(Protocol):
    """What a job sees of the loop's run (:class:`cuboidcli.learn.trainer.Run` is the one the loop makes):
    its counters, where it writes, the processes and the device, the clock and the log."""

    ctx: DistContext
    device: torch.device
    out_dir: Path
    epoch: int
    """Epochs done."""
    step: int
    """Optimizer steps done."""
    best: float
    """The best validation value so far."""

    def elapsed(self) -> float:
        """Wall time of the run, all sessions."""
        ...

    def time_fraction(self) -> float:
        """Share of the run's time limit used (0 without one)."""
        ...

    def emit(self, record: dict) -> None:
        """Report a record (rank 0) without logging it."""
        ...


@dataclass
class StepResult:
    """What one optimizer step reports."""

    metrics: dict[str, float]
    """Averaged over the steps of a log record and of an epoch record."""
    fields: dict = field(default_factory=dict)
    """Written as they are (the latest step's) into the step record: lr, the scenes of the step, ..."""
    items: int = 0
    """Sets, images or scenes the step saw over all ranks: the step record's rate (``rate_key``)."""


@dataclass
class Validation:
    value: float
    """What selects the best weights."""
    record: dict
    """The ``val`` record's fields (metrics)."""


class TrainingJob(ABC):
    """One kind of training, run by :func:`~cuboidcli.learn.trainer.run_job`. Subclasses set the class
    attributes that name their records and files and implement the abstract methods; the others have
    defaults."""

    name: ClassVar[str] = "training"
    """In messages ("cuboids train NAME")."""
    state_kind: ClassVar[str]
    """The ``kind`` of its training states (``last.pt``)."""
    step_event: ClassVar[str] = "step"
    """The ``event`` of its step records."""
    end_event: ClassVar[str] = "end"
    """The ``event`` of its final record."""
    rate_key: ClassVar[str | None] = None
    """Key of the step record's throughput: items (:attr:`StepResult.items`) per second."""
    lower_is_better: ClassVar[bool] = False
    """Validation values: lower ones are better (a residual, an error), else higher ones (an AUC)."""
    initial_is_candidate: ClassVar[bool] = False
    """The initial validation's weights may be the best ones (fine-tuning), else it is only logged."""
    distributed: ClassVar[bool] = True
    """Supports data-parallel runs under torchrun; False: refused with WORLD_SIZE > 1."""

    optimizer: torch.optim.Optimizer | None = None
    """Set by :meth:`setup`; its state goes into ``last.pt`` and comes back on resume."""

    @abstractmethod
    def setup(self, run: RunView, state: dict | None) -> None:
        """Load the data, build the networks and :attr:`optimizer`; with ``state`` (resuming), restore the
        networks and the job's own generators from it. ``run.step``, ``run.epoch`` and ``run.best`` are
        already restored; the optimizer and torch's global RNG are restored after this returns."""

    @abstractmethod
    def batches(self, run: RunView) -> Iterable:
        """The items of the next epoch, one per step (a step-based job may yield without end)."""

    @abstractmethod
    def step(self, run: RunView, batch) -> StepResult:
        """One optimizer step on ``batch`` (``run.step`` counts the steps done before it)."""

    @abstractmethod
    def validate(self, run: RunView) -> Validation | None:
        """Validate the current networks; None when there is nothing to validate on."""

    @abstractmethod
    def state(self, run: RunView) -> dict:
        """The job's entries of the training state (its networks, configs, generators). Called on every
        rank (it may gather); rank 0 writes the file."""

    @abstractmethod
    def networks(self) -> dict[str, torch.nn.Module]:
        """The networks being trained, by name: their parameters are counted and hashed."""

    @abstractmethod
    def best_weights(self, run: RunView, validation: dict) -> dict[str, dict]:
        """The weights files to write when the validation improved: file name -> weights dict."""

    def settings(self, run: RunView) -> dict:
        """The resolved settings, for ``config.json``."""
        return {}

    def start_fields(self, run: RunView) -> dict:
        """More fields of the ``start`` record."""
        return {}

    def end_fields(self, run: RunView) -> dict:
        """More fields of the final record."""
        return {}

    def agreement(self) -> object:
        """What every rank must hold equal besides the weights (the names of its data), checked once."""
        return None


class OneNetJob(TrainingJob):
    """A job that trains one network, :attr:`net` (built from :attr:`net_cfg`), under the trainer's config
    dataclass :attr:`cfg`. Its training state holds the net's config (``config``) and weights
    (``state_dict``) and the trainer's config (``train_config``) besides the entries of
    :meth:`more_state`."""

    net_name: ClassVar[str]
    """The network's name in :meth:`networks`."""
    cfg: object
    """The trainer's config (a dataclass)."""
    net: torch.nn.Module
    """Set by :meth:`setup`."""
    net_cfg: NetConfig
    """The net's config (set by :meth:`setup` at the latest)."""

    @abstractmethod
    def more_state(self, run: RunView) -> dict:
        """The job's entries of the training state besides the net and the configs (its generators, the
        configs of its data and fitting)."""

    def state(self, run: RunView) -> dict:
        own = {"config": self.net_cfg.to_dict(), "state_dict": self.net.state_dict()}
        return {**own, **self.more_state(run), "train_config": asdict(self.cfg)}

    def networks(self) -> dict[str, torch.nn.Module]:
        return {self.net_name: self.net}

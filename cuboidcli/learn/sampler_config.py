"""The settings of sampler training (:class:`SamplerTrainConfig`) and those it shares with fine-tuning
(:class:`SamplerSchedule`)."""

from __future__ import annotations

from dataclasses import dataclass, fields

from cuboidcli.fitting.config import FitConfig
from cuboidcli.learn.run_config import RunFields
from cuboidcli.learn.sampler_loss import CORR_MODES, LossParams, LossSettings, occlusion_threshold


@dataclass(frozen=True)
class SamplerSchedule(LossSettings, RunFields):
    """The settings a sampler training run (:class:`SamplerTrainConfig`) and a fine-tuning run
    (:class:`cuboidcli.learn.finetune.FinetuneConfig`) share: the sampling-weight network's loss
    (:class:`~cuboidcli.learn.sampler_loss.LossSettings`), the frames, validation and the run
    (:class:`~cuboidcli.learn.run_config.RunFields`). Defaults are the
    sampler trainer's; a subclass redeclares a field to give it another default (and docstring)."""

    epochs: int = 25
    """N_e: epochs (also the length of the tau_c schedule)."""
    lr: float = 1e-4
    """Adam learning rate (the paper: 1e-5 on a GPU).

    The paper uses 1e-5 for 25 epochs of the 795 NYU training frames (~10k Adam
    steps at B = 2); a CPU budget of a few thousand steps moves each weight by at most ~steps * lr, so the
    default is 10x the paper's. Lower it (or use 1e-5) for long runs if the validation AUC oscillates."""
    batch: int = 2
    """B: scenes per optimizer step (over all processes)."""
    instances: int = 8
    """|M|: sequential instances per scene."""
    corr_mode: str = "positive"
    """l_corr variant (see sampler_loss.LossSettings.corr_mode); "paper" is the paper's plain sum."""
    scenes_per_epoch: int | None = None
    """Scenes per epoch; None = every training frame once (the paper used 500 random scenes for SMH)."""
    grid_step: int = 8
    """Fitting points: every n-th pixel (8: 60x80 of 480x640)."""
    workers: int = 1
    """Threads reading and preparing frames."""
    val_hypotheses: int = 256
    """|H| when fitting the validation frames (the paper tests with 4096)."""
    val_frames: int | None = None
    """Validate on at most this many val frames (None = all)."""
    validate_initial: bool = True
    """Validate the untrained net before the first epoch (a reference point in the log)."""

    def __post_init__(self) -> None:
        if self.corr_mode not in CORR_MODES:
            raise ValueError(f"corr_mode must be one of {CORR_MODES}, got {self.corr_mode!r}")
        if self.samples_k < 2:
            raise ValueError("samples_k (K) must be at least 2: the baseline of K = 1 cancels the signal")
        for name in ("epochs", "batch", "hypotheses", "instances", "grid_step", "threads", "workers"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")


@dataclass(frozen=True)
class SamplerTrainConfig(SamplerSchedule):
    """Schedule and bookkeeping of a sampler training run; defaults are the paper's NYU values except lr.
    The fields it shares with fine-tuning are :class:`SamplerSchedule`'s."""

    tau_c_start_sq_m2: float = 1.0
    """tau_c at epoch 0, m^2 (the "1" of the paper's schedule)."""
    keep_snapshots: int = 3
    """epoch_XXX.pt files kept."""

    def loss_params(self, fit: FitConfig, epoch: int) -> LossParams:
        """The loss of an instance in ``epoch``: this config's :class:`LossSettings`, ``fit``'s minimal set
        and inlier function and the epoch's occlusion threshold."""
        return LossParams(
            **{f.name: getattr(self, f.name) for f in fields(LossSettings)},
            min_set=fit.min_set,
            tau_sq_m2=fit.tau_sq_m2,
            beta=fit.beta,
            tau_c_sq_m2=occlusion_threshold(epoch, self.epochs, fit.tau_sq_m2, self.tau_c_start_sq_m2),
        )

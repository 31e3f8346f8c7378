"""The settings of a fine-tuning run (``cuboids train finetune``), apart from the loop it runs in."""

from __future__ import annotations

from dataclasses import dataclass

from cuboidcli.learn.sampler_config import SamplerSchedule

#: The solvers a fine-tuning run can train with.
SOLVERS = ("neural", "numerical")


@dataclass(frozen=True)
class FinetuneConfig(SamplerSchedule):
    """Schedule of a fine-tuning run; defaults follow the paper's fine-tuning column except the rates. The
    fields it shares with sampler training are :class:`~cuboidcli.learn.sampler_config.SamplerSchedule`'s,
    with the defaults redeclared here."""

    rgb: bool = False
    """Fine-tune from RGB: the depth network's prediction is the input (needs RGB frames)."""
    solver: str = "neural"
    """neural (fine-tuned too) | numerical (implicit-function gradients; not trained)."""
    epochs: int = 10
    """Epochs."""
    lr: float = 1e-5
    """Adam learning rate of the sampling-weight network (the paper: 1e-7 for 25 GPU epochs); 0 keeps a
    network fixed (also for solver_lr and depth_lr)."""
    solver_lr: float | None = None
    """Of the neural solver; None = lr."""
    depth_lr: float | None = None
    """Of the depth network; None = lr."""
    alpha: float = 1000.0
    grad_top: int = 4
    """The differentiable expectation E_h[l] runs over the hypotheses of the grad_top largest gains of a
    set (softmax renormalised over them); with alpha = 1000 the rest carry a negligible selection weight,
    and the occlusion-aware count with gradients is the most expensive part of a step."""
    kappa_corr: float = 0.0
    kappa_entropy: float = 0.0
    kappa_im: float = 0.0
    val_hypotheses: int = 512

    def __post_init__(self) -> None:
        if self.solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {self.solver!r}")
        if self.solver == "numerical" and not self.rgb:
            raise ValueError(
                "fine-tuning with the numerical solver on depth input trains only the sampler: use "
                "'cuboids train sampler', or --solver neural, or --rgb"
            )
        if self.device != "cpu":
            raise ValueError(f"fine-tuning runs on the CPU in this version (got device {self.device!r})")
        super().__post_init__()
        for name in ("val_hypotheses", "grad_top"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")
        for name in ("lr", "solver_lr", "depth_lr"):
            value = getattr(self, name)
            if value is not None and not value >= 0:
                raise ValueError(f"{name} must be positive (or 0: keep the network fixed), got {value}")

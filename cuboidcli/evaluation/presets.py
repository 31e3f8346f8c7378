"""The paper's baselines and variants (Sec. 4 "Baselines", Table 1) as named settings.

A preset overrides fields of :class:`~cuboidcli.fitting.config.FitConfig` and may set the AUC thresholds.
Presets combine left to right (``"seqransac,outdoor"``); explicit command-line options win over both.
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields, replace

from cuboidcli.fitting.config import OUTDOOR, FitConfig
from cuboidcli.fitting.parts import SAMPLERS, SOLVERS
from cuboidcli.io.depth import InputError

#: The samplers and solvers an evaluation runs: no ``local`` (sequential with every set localised), no
#: ``onnx`` (an evaluation takes no ONNX solver file).
EVAL_SAMPLERS = tuple(s for s in SAMPLERS if s != "local")
EVAL_SOLVERS = tuple(s for s in SOLVERS if s != "onnx")


@dataclass(frozen=True)
class Preset:
    name: str
    description: str
    fit: dict = field(default_factory=dict)
    """FitConfig field overrides."""
    auc_cm: tuple[float, ...] | None = None
    """AUC upper bounds in cm; None keeps the current ones."""


#: The paper's estimator: global minimal sets, one batch per step, no winner refinement (or growing);
#: presets that reproduce its rows use these settings.
_PAPER = {
    "refine": False,
    "local_fraction": 0.0,
    "max_batches": 1,
    "hypotheses": 4096,
    "slab_max_m": None,
    "theta_log_factor": 9.0,
    "align": "free",
}

PRESETS: dict[str, Preset] = {
    p.name: p
    for p in (
        Preset("default", "FitConfig defaults (this project's estimator, including winner refinement)"),
        Preset(
            "ours",
            "the paper's method: learned sampling weights, numerical solver, OAI, no refinement",
            {"sampler": "learned", "solver": "numerical", "occlusion_aware": True, **_PAPER},
        ),
        Preset(
            "ours-neural",
            "the paper's method with the neural solver",
            {"sampler": "learned", "solver": "neural", "occlusion_aware": True, **_PAPER},
        ),
        Preset(
            "seqransac-oai",
            "the paper's Sequential RANSAC baseline with occlusion-aware inlier counting",
            {"sampler": "sequential", "solver": "numerical", "occlusion_aware": True, **_PAPER},
        ),
        Preset(
            "seqransac",
            "the paper's Sequential RANSAC baseline without occlusion-aware inlier counting",
            {"sampler": "sequential", "solver": "numerical", "occlusion_aware": False, **_PAPER},
        ),
        Preset(
            "uniform",
            "uniform sampling of global minimal sets (ablation)",
            {"sampler": "uniform", "local_fraction": 0.0},
        ),
        Preset(
            "paper",
            "the paper's plain estimator: global minimal sets, one batch per step, no refinement",
            dict(_PAPER),
        ),
        Preset(
            "outdoor",
            "outdoor scenes (the paper's SMH experiments): tau, size bounds, AUC@50/10 cm",
            dict(OUTDOOR),
            auc_cm=(50.0, 10.0),
        ),
    )
}


def resolve(
    names: str | None, base: FitConfig | None = None, auc_cm: tuple[float, ...] = (20.0, 5.0)
) -> tuple[FitConfig, tuple[float, ...], list[str]]:
    """Apply comma-separated preset names to ``base``: (config, AUC thresholds in cm, applied names)."""
    config = base or FitConfig()
    applied: list[str] = []
    valid = {f.name for f in fields(FitConfig)}
    for name in [n.strip() for n in (names or "").split(",") if n.strip()]:
        if name not in PRESETS:
            raise InputError(f"unknown preset {name!r}; choose from {', '.join(PRESETS)}")
        preset = PRESETS[name]
        unknown = set(preset.fit) - valid
        if unknown:  # a field the estimator does not have (yet)
            raise InputError(f"preset {name!r} sets {', '.join(sorted(unknown))}, unknown to this FitConfig")
        config = replace(config, **preset.fit)
        if preset.auc_cm is not None:
            auc_cm = preset.auc_cm
        applied.append(name)
    return config, tuple(auc_cm), applied

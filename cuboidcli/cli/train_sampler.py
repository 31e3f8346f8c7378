"""``cuboids train sampler``: train the sampling-weight network (paper Sec. 3.5) on a dataset folder.

Registered on the ``train`` sub-command group by :func:`register`; the training itself lives in
:mod:`cuboidcli.learn.sampler_train`.
"""

from __future__ import annotations

import math
from pathlib import Path

import typer

from cuboidcli.cli import train_options as opt
from cuboidcli.cli.common import check_training_paths, console, fail, resolve_device, training_run
from cuboidcli.learn.sampler_config import SamplerTrainConfig
from cuboidcli.nets.sampler import SamplerNetConfig

#: --prior: the sequential prior of the shipped sampler (models/sampler_v2.md); SamplerNetConfig keeps the
#: paper's "none" for nets built without a config.
PRIOR = "unexplained"
#: The output folder by default.
OUTPUT = "runs/sampler"


def _print_event(record: dict) -> None:
    kind = record.get("event")
    if kind == "start":
        console.print(
            f"sampler net: {record['parameters']:,} parameters; {record['train_frames']} train / "
            f"{record['val_frames']} val frames ({record['split']}); from epoch {record['epoch']} "
            f"to {record['epochs']}",
            highlight=False,
        )
    elif kind == "step":
        console.print(
            f"epoch {record['epoch']} step {record['step']}: expected I_c {-record['expected_loss']:.3f} "
            f"best gain {record['best_gain']:.3f} corr {record['corr']:+.2f} H(q) {record['entropy']:.2f} "
            f"({record['seconds']:.1f} s, {record['scenes_per_s']:.2f} scenes/s)",
            highlight=False,
        )
    elif kind == "val":
        key = record["key"]
        tag = " (untrained)" if record.get("initial") else (" *best*" if record.get("best") else "")
        console.print(
            f"[bold]val epoch {record['epoch']}[/]{tag}: {key} {record[key]:.2f}, "
            f"inlier fraction {record['mean_inlier_fraction']:.3f}, {record['cuboids']:.1f} cuboids "
            f"({record['seconds']:.0f} s)",
            highlight=False,
        )
    elif kind == "epoch":
        console.print(
            f"epoch {record['epoch']} done in {record['seconds']:.0f} s: mean expected I_c "
            f"{-record['expected_loss']:.3f}",
            highlight=False,
        )
    elif kind == "end":
        best = record["best"]
        console.print(
            f"done: {record['epochs_done']} epochs in {record['seconds'] / 60:.1f} min; best "
            f"{best if math.isfinite(best) else 'n/a'}; weights {record['weights']}",
            highlight=False,
        )


@opt.trains(SamplerTrainConfig, SamplerNetConfig)
@opt.multi_process("sampler DATA --output OUT")
def train_sampler_cmd(
    data: Path = typer.Argument(..., help="Dataset folder (generic layout; splits.json gives train/val)."),
    epochs: int = opt.epochs_option(SamplerTrainConfig),
    lr: float = opt.lr_option(SamplerTrainConfig),
    batch: int = opt.train_option(SamplerTrainConfig, "batch"),
    hypotheses: int = opt.train_option(SamplerTrainConfig, "hypotheses"),
    instances: int = opt.train_option(SamplerTrainConfig, "instances"),
    samples_k: int = opt.train_option(SamplerTrainConfig, "samples_k"),
    alpha: float = opt.train_option(SamplerTrainConfig, "alpha", more="1000 when fine-tuning."),
    scenes_per_epoch: int | None = opt.scenes_per_epoch_option(SamplerTrainConfig),
    grid_step: int = opt.train_option(SamplerTrainConfig, "grid_step"),
    width: int = opt.channels_option(SamplerNetConfig),
    blocks: int = opt.train_option(SamplerNetConfig, "blocks"),
    upsample: int = opt.train_option(SamplerNetConfig, "upsample"),
    prior: str = typer.Option(
        PRIOR, "--prior", help="'unexplained': maps on top of the sequential weights; 'none': plain."
    ),
    kappa_corr: float = opt.train_option(SamplerTrainConfig, "kappa_corr"),
    tau_c_start_sq_m2: float = opt.train_option(
        SamplerTrainConfig, "tau_c_start_sq_m2", "--tau-c-start", more="0.008: the test value throughout."
    ),
    corr_mode: str = opt.train_option(
        SamplerTrainConfig,
        "corr_mode",
        text="'positive': penalise positive correlations only; 'paper': the sum.",
    ),
    val_hypotheses: int = opt.val_hypotheses_option(SamplerTrainConfig),
    val_frames: int | None = opt.val_frames_option(SamplerTrainConfig),
    workers: int = opt.workers_option(SamplerTrainConfig),
    resume: Path | None = opt.resume_option("or an epoch_*.pt snapshot."),
    out: Path = opt.output_option(OUTPUT),
    seed: int = opt.seed_option(SamplerTrainConfig),
    threads: int = opt.threads_option(SamplerTrainConfig),
    device: str = opt.train_device_option(SamplerTrainConfig),
    max_minutes: float | None = opt.max_minutes_option(SamplerTrainConfig),
    backend: str | None = opt.backend_option(),
    old_width: int | None = opt.old_channels_option(),
    old_out: Path | None = opt.old_output_option(),
) -> None:
    """Train the sampling-weight network on DATA; the best weights go to OUT/sampler_v2.pt.

    Use them with: cuboids fit ... --sampler learned --weights OUT
    """
    out = opt.output_folder(out, old_out, OUTPUT)
    width = opt.channels(width, old_width, SamplerNetConfig)
    options = dict(locals())
    from cuboidcli.learn.sampler_train import train_sampler

    check_training_paths(data, resume, out)
    if blocks < 0:
        fail(f"--blocks must be at least 0 (got {blocks})")
    cfg = opt.config_of(SamplerTrainConfig, options, device=resolve_device(device))
    net_cfg = opt.config_of(SamplerNetConfig, options)
    with training_run(out, resume):
        train_sampler(cfg, data, out, net_cfg=net_cfg, resume=resume, on_event=_print_event, backend=backend)


def register(train_app: typer.Typer) -> None:
    """Add the ``sampler`` command to the ``cuboids train`` group."""
    train_app.command("sampler")(train_sampler_cmd)

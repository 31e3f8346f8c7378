"""``cuboids train seed``: train the first-point sampler of localised minimal sets (models/sampler_v3.pt).

Registered on the ``train`` sub-command group by :func:`register`; the training itself lives in
:mod:`cuboidcli.learn.seed_train`.
"""

from __future__ import annotations

from pathlib import Path

import typer

from cuboidcli.cli import train_options as opt
from cuboidcli.cli.common import check_training_paths, console, training_run
from cuboidcli.learn.seed_train import SeedTrainConfig
from cuboidcli.nets.sampler import SamplerNetConfig

#: The output folder by default.
OUTPUT = "runs/seed"


def _print_event(record: dict) -> None:
    kind = record.get("event")
    if kind == "records":
        console.print(f"recorded seed scores: {record['scenes']} scenes, {record['records']} steps")
    elif kind == "records_done":
        console.print(f"{record['records']} records in {record['seconds']:.0f} s", highlight=False)
    elif kind == "start":
        console.print(
            f"first-point net: {record['parameters']:,} parameters; {record['records']} records of "
            f"{record['scenes']} scenes; from epoch {record['epoch']} to {record['epochs']}",
            highlight=False,
        )
    elif kind == "epoch":
        tag = " *best*" if record.get("best") else ""
        console.print(
            f"epoch {record['epoch']}: mean KL {record['kl']:.3f}{tag} ({record['seconds']:.0f} s)",
            highlight=False,
        )
    elif kind == "end":
        note = " (stopped by --max-minutes)" if record.get("timed_out") else ""
        console.print(
            f"done: epoch {record['epoch']} in {record['seconds'] / 60:.1f} min{note}; weights "
            f"{record['weights']}",
            highlight=False,
        )


@opt.trains(SeedTrainConfig)
def train_seed_cmd(
    data: Path = typer.Argument(..., help="Dataset folder (generic layout; its train split is used)."),
    scenes: int | None = opt.train_option(
        SeedTrainConfig, "scenes", text="Training scenes used (the first ones).", show_default="all"
    ),
    steps: int = opt.train_option(SeedTrainConfig, "steps"),
    hypotheses: int = opt.train_option(SeedTrainConfig, "hypotheses"),
    kappa: float = opt.train_option(SeedTrainConfig, "kappa"),
    epochs: int = opt.epochs_option(SeedTrainConfig),
    lr: float = opt.lr_option(SeedTrainConfig),
    width: int = opt.channels_option(SeedTrainConfig, doc=SamplerNetConfig),
    blocks: int = opt.train_option(SeedTrainConfig, "blocks", doc=SamplerNetConfig),
    upsample: int = opt.train_option(
        SeedTrainConfig, "upsample", text="The net runs on the fitting grid upsampled by this power of two."
    ),
    resume: Path | None = opt.resume_option(),
    out: Path = opt.output_option(OUTPUT),
    seed: int = opt.seed_option(SeedTrainConfig),
    max_minutes: float | None = opt.max_minutes_option(SeedTrainConfig),
    old_width: int | None = opt.old_channels_option(),
    old_out: Path | None = opt.old_output_option(),
) -> None:
    """Train the first-point sampler on DATA: record how well seeds drawn with the Sequential-RANSAC weights
    do along a sequential fit of each training scene, then fit the one-map network to those scores. The
    weights go to OUT/sampler_v3.pt after every epoch.

    Use them with: cuboids fit ... --sampler learned --weights OUT/sampler_v3.pt
    """
    out = opt.output_folder(out, old_out, OUTPUT)
    width = opt.channels(width, old_width, SeedTrainConfig)
    options = dict(locals())
    from cuboidcli.learn.seed_train import train_seed_sampler

    check_training_paths(data, resume, out)
    cfg = opt.config_of(SeedTrainConfig, options)
    with training_run(out, resume):
        train_seed_sampler(data, out, cfg, on_event=_print_event, resume=resume)


def register(train_app: typer.Typer) -> None:
    """Add the ``seed`` command to the ``cuboids train`` group."""
    train_app.command("seed")(train_seed_cmd)

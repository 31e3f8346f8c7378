"""``cuboids train finetune``: end-to-end fine-tuning (paper Sec. 4, "End-to-end network fine-tuning").

Registered on the ``train`` group by :func:`register`; the work is in :mod:`cuboidcli.learn.finetune`.
"""

from __future__ import annotations

import math
from pathlib import Path

import typer

from cuboidcli.cli import train_options as opt
from cuboidcli.cli.common import check_training_paths, console, fail, resolve_device, training_run
from cuboidcli.learn.finetune_config import FinetuneConfig

#: The output folder by default.
OUTPUT = "runs/finetune"


def _print_event(record: dict) -> None:
    kind = record.get("event")
    if kind == "start":
        params = ", ".join(f"{k} {v:,}" for k, v in record["parameters"].items())
        console.print(
            f"fine-tuning {params} parameters; {record['train_frames']} train / {record['val_frames']} val "
            f"frames ({record['split']}); from epoch {record['epoch']} to {record['epochs']}",
            highlight=False,
        )
    elif kind == "step":
        console.print(
            f"epoch {record['epoch']} step {record['step']}: expected I_c {-record['expected_loss']:.3f} "
            f"best gain {record['best_gain']:.3f} ({record['scenes_per_s']:.2f} scenes/s)",
            highlight=False,
        )
    elif kind == "val":
        tag = " (before fine-tuning)" if record.get("initial") else (" *best*" if record.get("best") else "")
        console.print(
            f"[bold]val epoch {record['epoch']}[/]{tag}: AUC@20 {record['auc20cm_pct']:.2f} %, AUC@5 "
            f"{record['auc5cm_pct']:.2f} %, coverage {record['coverage_pct']:.1f} %, "
            f"{record['cuboids']:.1f} cuboids ({record['seconds']:.0f} s)",
            highlight=False,
        )
    elif kind == "epoch":
        console.print(f"epoch {record['epoch']} done in {record['seconds']:.0f} s", highlight=False)
    elif kind == "end":
        best = record["best"]
        console.print(
            f"done: {record['epochs_done']} epochs in {record['seconds'] / 60:.1f} min; best AUC@20 "
            f"{f'{best:.2f} %' if math.isfinite(best) else 'n/a'}; weights in {record['out']}",
            highlight=False,
        )


@opt.trains(FinetuneConfig)
@opt.multi_process("finetune DATA --output OUT", per="group of CPU cores")
def train_finetune_cmd(
    data: Path = typer.Argument(..., help="Dataset folder (generic layout; splits.json gives train/val)."),
    rgb: bool = opt.train_option(
        FinetuneConfig, "rgb", "--rgb", text="Fine-tune from RGB through the depth network too."
    ),
    solver: str = opt.train_option(
        FinetuneConfig, "solver", text="neural (fine-tuned) or numerical (needs --rgb)."
    ),
    sampler_weights: Path | None = typer.Option(
        None, "--sampler-weights", help="Start: sampler .pt or folder.", show_default="models/sampler_v2.pt"
    ),
    solver_weights: Path | None = typer.Option(
        None, "--solver-weights", help="Start: neural solver .pt.", show_default="the shipped one"
    ),
    depth_weights: Path | None = typer.Option(
        None, "--depth-weights", help="Start: depth network .pt.", show_default="the shipped one"
    ),
    epochs: int = opt.epochs_option(FinetuneConfig),
    lr: float = opt.lr_option(FinetuneConfig),
    solver_lr: float | None = opt.train_option(
        FinetuneConfig, "solver_lr", text="Of the neural solver.", show_default="--lr"
    ),
    depth_lr: float | None = opt.train_option(
        FinetuneConfig, "depth_lr", text="Of the depth network.", show_default="--lr"
    ),
    batch: int = opt.train_option(FinetuneConfig, "batch"),
    hypotheses: int = opt.train_option(FinetuneConfig, "hypotheses"),
    instances: int = opt.train_option(FinetuneConfig, "instances"),
    samples_k: int = opt.train_option(FinetuneConfig, "samples_k"),
    alpha: float = opt.train_option(FinetuneConfig, "alpha"),
    scenes_per_epoch: int | None = opt.scenes_per_epoch_option(FinetuneConfig),
    grid_step: int = opt.train_option(FinetuneConfig, "grid_step"),
    val_hypotheses: int = opt.val_hypotheses_option(FinetuneConfig),
    val_frames: int | None = opt.val_frames_option(FinetuneConfig),
    workers: int = opt.workers_option(FinetuneConfig),
    resume: Path | None = opt.resume_option(),
    out: Path = opt.output_option(OUTPUT),
    seed: int = opt.seed_option(FinetuneConfig),
    threads: int = opt.threads_option(FinetuneConfig),
    device: str = opt.train_device_option(FinetuneConfig),
    max_minutes: float | None = opt.max_minutes_option(FinetuneConfig),
    backend: str | None = opt.backend_option(),
    old_out: Path | None = opt.old_output_option(),
) -> None:
    """Fine-tune sampler + neural solver (depth input) or depth net + sampler (+ solver) (--rgb) end to end.

    The best weights (validation AUC@20) go to OUT as sampler_v2.pt, solver_v2.pt and depth_v2.pt; use
    them with: cuboids fit ... --weights OUT (and --depth-model OUT/depth_v2.pt for RGB input).
    """
    out = opt.output_folder(out, old_out, OUTPUT)
    options = dict(locals())
    from cuboidcli.learn.finetune import finetune

    check_training_paths(data, resume, out)
    for name, path in (("--solver-weights", solver_weights), ("--depth-weights", depth_weights)):
        if path is not None and not path.is_file():
            fail(f"{name} {path}: no such file")
    if sampler_weights is not None and not sampler_weights.exists():
        fail(f"--sampler-weights {sampler_weights}: no such file or folder")
    cfg = opt.config_of(FinetuneConfig, options, device=resolve_device(device))
    with training_run(out, resume):
        finetune(
            cfg,
            data,
            out,
            sampler_weights=sampler_weights,
            solver_weights=solver_weights,
            depth_weights=depth_weights,
            resume=resume,
            on_event=_print_event,
            backend=backend,
        )


def register(train_app: typer.Typer) -> None:
    """Add the ``finetune`` command to the ``cuboids train`` group."""
    train_app.command("finetune")(train_finetune_cmd)

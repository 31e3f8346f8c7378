"""``cuboids train finetune``: end-to-end fine-tuning (paper Sec. 4, "End-to-end network fine-tuning").

Registered on the ``train`` group by :func:`register`; the work is in :mod:`cuboidcli.learn.finetune`.
"""

from __future__ import annotations

import math
from pathlib import Path

import typer

from cuboidcli.cli.common import (
    check_training_paths,
    console,
    fail,
    no_empty_folder,
    resolve_device,
    user_errors,
)


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


def train_finetune_cmd(
    data: Path = typer.Argument(..., help="Dataset folder (generic layout; splits.json gives train/val)."),
    rgb: bool = typer.Option(False, "--rgb", help="Fine-tune from RGB through the depth network too."),
    solver: str = typer.Option("neural", "--solver", help="neural (fine-tuned) or numerical (needs --rgb)."),
    sampler_weights: Path | None = typer.Option(
        None, "--sampler-weights", help="Start: sampler .pt or folder [default: models/sampler_v2.pt]."
    ),
    solver_weights: Path | None = typer.Option(
        None, "--solver-weights", help="Start: neural solver .pt [default: the shipped one]."
    ),
    depth_weights: Path | None = typer.Option(
        None, "--depth-weights", help="Start: depth network .pt [default: the shipped one]."
    ),
    epochs: int = typer.Option(10, "--epochs", help="Epochs."),
    lr: float = typer.Option(1e-5, "--lr", help="Adam lr of the sampler (paper: 1e-7); 0: fixed."),
    solver_lr: float | None = typer.Option(None, "--solver-lr", help="Of the neural solver [default: --lr]."),
    depth_lr: float | None = typer.Option(None, "--depth-lr", help="Of the depth network [default: --lr]."),
    batch: int = typer.Option(2, "--batch", help="B: scenes per optimizer step (over all processes)."),
    hypotheses: int = typer.Option(32, "--hypotheses", help="|H|: hypotheses per sampled set."),
    instances: int = typer.Option(8, "--instances", help="|M|: sequential instances per scene."),
    samples_k: int = typer.Option(2, "--samples-k", help="K: hypothesis sets per instance (>= 2)."),
    alpha: float = typer.Option(1000.0, "--alpha", help="alpha: selection softmax scale."),
    scenes_per_epoch: int | None = typer.Option(
        None, "--scenes-per-epoch", help="Scenes per epoch [default: every training frame once]."
    ),
    grid_step: int = typer.Option(8, "--grid-step", help="Fitting points: every n-th pixel."),
    val_hypotheses: int = typer.Option(512, "--val-hypotheses", help="|H| when fitting the val frames."),
    val_frames: int | None = typer.Option(None, "--val-frames", help="Validate on at most this many frames."),
    workers: int = typer.Option(1, "--workers", "-j", help="Threads reading and preparing the frames."),
    resume: Path | None = typer.Option(None, "--resume", help="Continue from OUT/last.pt."),
    out: Path = typer.Option(Path("runs/finetune"), "--out", "-o", help="Output folder."),
    seed: int = typer.Option(0, "--seed", help="Seeds the frame order and every draw."),
    threads: int = typer.Option(1, "--threads", help="torch CPU threads."),
    device: str = typer.Option("cpu", "--device", help="auto, cpu or cuda."),
    max_minutes: float | None = typer.Option(
        None, "--max-minutes", help="Stop after the epoch during which this much time has passed."
    ),
    backend: str | None = typer.Option(
        None, "--backend", help="torch.distributed backend under torchrun (gloo) [default: gloo on the CPU]."
    ),
) -> None:
    """Fine-tune sampler + neural solver (depth input) or depth net + sampler (+ solver) (--rgb) end to end.

    The best weights (validation AUC@20) go to OUT as sampler_v2.pt, solver_v2.pt and depth_v2.pt; use
    them with: cuboids fit ... --weights OUT (and --depth-model OUT/depth_v2.pt for RGB input).

    Multi-process (data parallel, one process per group of CPU cores), e.g. 2 processes:

        torchrun --standalone --nproc_per_node 2 -m cuboidcli.cli.main train finetune DATA --out OUT

    The --batch scenes of a step are split over the processes (use a multiple of their number), each
    process drawing its own hypotheses, and the gradients averaged; the val frames are split too.
    Process 0 alone prints and writes OUT, which must be shared for --resume; resuming with the same
    number of processes continues the run exactly.
    """
    from cuboidcli.learn.finetune import FinetuneConfig, finetune

    check_training_paths(data, resume, out)
    for name, path in (("--solver-weights", solver_weights), ("--depth-weights", depth_weights)):
        if path is not None and not path.is_file():
            fail(f"{name} {path}: no such file")
    if sampler_weights is not None and not sampler_weights.exists():
        fail(f"--sampler-weights {sampler_weights}: no such file or folder")
    try:
        cfg = FinetuneConfig(
            rgb=rgb,
            solver=solver,
            epochs=epochs,
            lr=lr,
            solver_lr=solver_lr,
            depth_lr=depth_lr,
            batch=batch,
            hypotheses=hypotheses,
            instances=instances,
            samples_k=samples_k,
            alpha=alpha,
            scenes_per_epoch=scenes_per_epoch,
            grid_step=grid_step,
            seed=seed,
            threads=threads,
            workers=workers,
            device=resolve_device(device),
            val_hypotheses=val_hypotheses,
            val_frames=val_frames,
            max_minutes=max_minutes,
        )
    except ValueError as e:
        fail(str(e))
    with user_errors(), no_empty_folder(out):
        try:
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
        except (ValueError, FileNotFoundError) as e:
            fail(str(e))
        except KeyboardInterrupt:
            fail(f"interrupted; continue with --resume {out / 'last.pt'}", code=130)


def register(train_app: typer.Typer) -> None:
    """Add the ``finetune`` command to the ``cuboids train`` group."""
    train_app.command("finetune")(train_finetune_cmd)

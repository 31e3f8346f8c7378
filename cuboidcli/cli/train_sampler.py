"""``cuboids train sampler``: train the sampling-weight network (paper Sec. 3.5) on a dataset folder.

Registered on the ``train`` sub-command group by :func:`register`; the training itself lives in
:mod:`cuboidcli.learn.sampler_train`.
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


def train_sampler_cmd(
    data: Path = typer.Argument(..., help="Dataset folder (generic layout; splits.json gives train/val)."),
    epochs: int = typer.Option(25, "--epochs", help="N_e: epochs (also the length of the tau_c schedule)."),
    lr: float = typer.Option(1e-4, "--lr", help="Adam learning rate (the paper: 1e-5 on a GPU)."),
    batch: int = typer.Option(2, "--batch", help="B: scenes per optimizer step (over all processes)."),
    hypotheses: int = typer.Option(32, "--hypotheses", help="|H|: hypotheses per sampled set."),
    instances: int = typer.Option(8, "--instances", help="|M|: sequential instances per scene."),
    samples_k: int = typer.Option(2, "--samples-k", help="K: hypothesis sets per instance (>= 2)."),
    alpha: float = typer.Option(10.0, "--alpha", help="alpha: selection softmax scale (1000 fine-tuning)."),
    scenes_per_epoch: int | None = typer.Option(
        None, "--scenes-per-epoch", help="Scenes per epoch [default: every training frame once]."
    ),
    grid_step: int = typer.Option(8, "--grid-step", help="Fitting points: every n-th pixel (8: 60x80)."),
    width: int = typer.Option(96, "--width", help="Channels of the network on the fitting grid."),
    blocks: int = typer.Option(4, "--blocks", help="Residual blocks of the network on the fitting grid."),
    upsample: int = typer.Option(
        4, "--upsample", help="Input resolution: the fitting grid times this power of two (8: the paper)."
    ),
    prior: str = typer.Option(
        "unexplained", "--prior", help="'unexplained': maps on top of the sequential weights; 'none': plain."
    ),
    kappa_corr: float = typer.Option(1.0, "--kappa-corr", help="Weight of the map-correlation loss."),
    tau_c_start: float = typer.Option(
        1.0, "--tau-c-start", help="tau_c at epoch 0, m^2 (the paper's 1; 0.008 = the test value throughout)."
    ),
    corr_mode: str = typer.Option(
        "positive", "--corr-mode", help="'positive': penalise positive correlations only; 'paper': the sum."
    ),
    val_hypotheses: int = typer.Option(256, "--val-hypotheses", help="|H| when fitting the val frames."),
    val_frames: int | None = typer.Option(None, "--val-frames", help="Validate on at most this many frames."),
    workers: int = typer.Option(1, "--workers", "-j", help="Threads reading and preparing the frames."),
    resume: Path | None = typer.Option(None, "--resume", help="Continue from a last.pt / epoch_*.pt file."),
    out: Path = typer.Option(Path("runs/sampler"), "--out", "-o", help="Output folder."),
    seed: int = typer.Option(0, "--seed", help="Seeds weights, frame order and every draw."),
    threads: int = typer.Option(1, "--threads", help="torch CPU threads."),
    device: str = typer.Option("cpu", "--device", help="auto, cpu or cuda."),
    max_minutes: float | None = typer.Option(
        None, "--max-minutes", help="Stop after the epoch during which this much time has passed."
    ),
    backend: str | None = typer.Option(
        None,
        "--backend",
        help="torch.distributed backend under torchrun (gloo, nccl); default nccl on CUDA, gloo on CPU.",
    ),
) -> None:
    """Train the sampling-weight network on DATA; the best weights go to OUT/sampler_v2.pt.

    Use them with: cuboids fit ... --sampler learned --weights OUT

    Multi-process (data parallel, one process per GPU or per group of CPU cores), e.g. 2 processes:

        torchrun --standalone --nproc_per_node 2 -m cuboidcli.cli.main train sampler DATA --out OUT

    The --batch scenes of a step are split over the processes (use a multiple of their number), each
    process drawing its own hypotheses, and the gradients averaged; the val frames are split too.
    Process 0 alone prints and writes OUT, which must be shared for --resume; resuming with the same
    number of processes continues the run exactly.
    """
    from cuboidcli.learn.sampler_train import SamplerTrainConfig, train_sampler
    from cuboidcli.nets.sampler import SamplerNetConfig

    check_training_paths(data, resume, out)
    if blocks < 0:
        fail(f"--blocks must be at least 0 (got {blocks})")
    device = resolve_device(device)
    try:
        cfg = SamplerTrainConfig(
            epochs=epochs,
            lr=lr,
            batch=batch,
            hypotheses=hypotheses,
            instances=instances,
            samples_k=samples_k,
            alpha=alpha,
            kappa_corr=kappa_corr,
            tau_c_start_sq_m2=tau_c_start,
            corr_mode=corr_mode,
            scenes_per_epoch=scenes_per_epoch,
            grid_step=grid_step,
            seed=seed,
            threads=threads,
            device=device,
            workers=workers,
            val_hypotheses=val_hypotheses,
            val_frames=val_frames,
            max_minutes=max_minutes,
        )
        net_cfg = SamplerNetConfig(width=width, blocks=blocks, upsample=upsample, prior=prior)
    except ValueError as e:
        fail(str(e))
    with user_errors(), no_empty_folder(out):
        try:
            train_sampler(
                cfg, data, out, net_cfg=net_cfg, resume=resume, on_event=_print_event, backend=backend
            )
        except ValueError as e:
            fail(str(e))
        except KeyboardInterrupt:
            fail(f"interrupted; continue with --resume {out / 'last.pt'}", code=130)


def register(train_app: typer.Typer) -> None:
    """Add the ``sampler`` command to the ``cuboids train`` group."""
    train_app.command("sampler")(train_sampler_cmd)

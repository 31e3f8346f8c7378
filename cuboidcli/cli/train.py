"""``cuboids train ...``: training commands of the learned components. Options only; the work is in
:mod:`cuboidcli.learn`. Each command is one function decorated with ``@train_app.command``."""

from __future__ import annotations

from pathlib import Path

import typer
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    TextColumn,
    TimeElapsedColumn,
    TimeRemainingColumn,
)

from cuboidcli.cli.common import console, fail, no_empty_folder, out, resolve_device

train_app = typer.Typer(help="Train the learned components (neural solver, ...).", no_args_is_help=True)


def register(app: typer.Typer) -> None:
    app.add_typer(train_app, name="train")


def _progress() -> Progress:
    return Progress(
        TextColumn("[bold]{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TextColumn("{task.fields[status]}"),
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        console=console,
    )


@train_app.command("solver")
def solver(
    iters: int = typer.Option(50000, "--iters", help="Optimizer steps (the paper: 150k at batch 4096, GPU)."),
    batch: int = typer.Option(256, "--batch", help="Synthetic minimal sets per step and process."),
    lr: float = typer.Option(3e-3, "--lr", help="Peak Adam learning rate (warm-up, then cosine decay)."),
    width: int = typer.Option(64, "--width", help="Feature channels d of the network (128 in the paper)."),
    layers: int = typer.Option(2, "--layers", help="Transformer encoder layers (4 in the paper)."),
    heads: int = typer.Option(4, "--heads", help="Attention heads; must divide --width."),
    ff: int = typer.Option(128, "--ff", help="Feed-forward hidden size of each layer."),
    out_dir: Path = typer.Option(Path("runs/solver"), "--out", help="Folder for logs and checkpoints."),
    resume: Path | None = typer.Option(
        None,
        "--resume",
        help="Continue from a training checkpoint (last.pt / step_*.pt) exactly; "
        "schedule, data and net shape are taken from it.",
    ),
    seed: int = typer.Option(0, "--seed", help="Seeds the initial weights and every synthetic batch."),
    threads: int = typer.Option(1, "--threads", help="CPU threads for torch (the cores may be shared)."),
    device: str = typer.Option("cpu", "--device", help="cpu, cuda or auto."),
    max_minutes: float | None = typer.Option(
        None,
        "--max-minutes",
        help="Time budget: the lr decays over whichever runs out first, --iters or these minutes of wall "
        "time, and training stops there (not bit-reproducible then).",
    ),
    val_every: int = typer.Option(1000, "--val-every", help="Validate and keep the best every N steps."),
    backend: str | None = typer.Option(
        None,
        "--backend",
        help="torch.distributed backend under torchrun (gloo, nccl); default nccl on CUDA, gloo on CPU.",
    ),
) -> None:
    """Pre-train the neural cuboid solver on synthetic boxes; best weights go to OUT/best.pt.

    The same weights are in OUT/solver_v2.pt, the name 'cuboids fit --solver neural --weights OUT' reads.

    Multi-process (data parallel, one process per GPU or per group of CPU cores), e.g. 2 processes:

        torchrun --standalone --nproc_per_node 2 -m cuboidcli.cli.main train solver --out runs/solver

    or torchrun ... $(which cuboids) train solver ... (the console script is a Python file);
    multi-node: --nnodes N --node_rank R --rdzv_endpoint HOST:PORT instead of --standalone. Each process
    draws --batch sets per step, so a step sees --batch x processes sets; --iters and the lr schedule
    count steps. Process 0 alone validates, prints and writes OUT, which must be shared for --resume.
    """
    from cuboidcli.learn.distributed import launched_rank
    from cuboidcli.learn.solver_train import SolverTrainConfig, train_solver
    from cuboidcli.nets.solver import SolverNetConfig

    for name, value in (
        ("--iters", iters),
        ("--batch", batch),
        ("--width", width),
        ("--layers", layers),
        ("--heads", heads),
        ("--ff", ff),
        ("--threads", threads),
        ("--val-every", val_every),
    ):
        if value < 1:
            fail(f"{name} must be at least 1 (got {value})")
    if width % heads:
        fail(f"--width {width} is not divisible by --heads {heads}; pick e.g. --heads 4")
    if lr <= 0:
        fail(f"--lr must be positive (got {lr})")
    if resume is not None and not resume.is_file():
        fail(f"--resume {resume}: no such file; pass {out_dir / 'last.pt'} or a step_*.pt checkpoint")
    cfg = SolverTrainConfig(
        iters=iters,
        batch=batch,
        lr=lr,
        warmup=min(500, max(1, iters // 20)),
        seed=seed,
        threads=threads,
        device=resolve_device(device),
        max_minutes=max_minutes,
        val_every=val_every,
        ckpt_every=val_every,
    )
    net_cfg = SolverNetConfig(width=width, layers=layers, heads=heads, ff=ff)

    # Under torchrun only rank 0 reports; the others would draw duplicate progress bars.
    main_rank = launched_rank() == 0
    progress_bar = _progress()
    progress_bar.disable = not main_rank
    with no_empty_folder(out_dir):
        progress, task = progress_bar, None  # shown once training starts: a refused run prints its error only

        def on_event(record: dict) -> None:
            nonlocal task
            kind = record["event"]
            if kind == "start":
                progress.start()
                task = progress.add_task("solver", total=record["iters"], status="")
                progress.update(task, completed=record["iteration"])
                console.print(f"solver net: {record['parameters']:,} parameters; logs in {out_dir}")
            elif kind == "train":
                status = f"loss {record['loss_m2']:.2e} m² · {record['sets_per_s']:,.0f} sets/s"
                progress.update(task, completed=record["iteration"], status=status)
            elif kind == "val":
                star = " (best)" if record["best"] else ""
                console.print(
                    f"step {record['iteration']}: validation mean distance {record['clean_mean_cm']:.2f} cm "
                    f"clean, {record['noisy_mean_cm']:.2f} cm noisy{star}"
                )

        try:
            final = train_solver(cfg, net_cfg, out_dir, resume=resume, on_event=on_event, backend=backend)
        except ValueError as e:
            fail(str(e))
        finally:
            if task is not None:
                progress.stop()
    if not main_rank:
        return
    note = " (stopped by --max-minutes)" if final["timed_out"] else ""
    out.print(f"done at step {final['iteration']}{note}; best weights: {final['best']}")


from cuboidcli.cli import train_sampler as _train_sampler  # noqa: E402

_train_sampler.register(train_app)
from cuboidcli.cli import train_finetune as _train_finetune  # noqa: E402

_train_finetune.register(train_app)
from cuboidcli.cli import train_depth as _train_depth  # noqa: E402

_train_depth.register(train_app)

"""``cuboids train ...``: training commands of the learned components. Options only; the work is in
:mod:`cuboidcli.learn`. Each command is one function decorated with ``@train_app.command``."""

from __future__ import annotations

from pathlib import Path

import click
import typer
import typer.main
from rich.progress import TimeElapsedColumn, TimeRemainingColumn

from cuboidcli.cli import train_options as opt
from cuboidcli.cli.common import console, fail, out, progress_bar, resolve_device, training_run
from cuboidcli.learn.solver_train import SolverTrainConfig
from cuboidcli.nets.solver import SolverNetConfig

train_app = typer.Typer(
    name="train", help="Train the learned components (neural solver, ...).", no_args_is_help=True
)


def group() -> click.Group:
    """The ``cuboids train`` group as a click command, for :data:`cuboidcli.cli.main.LAZY_GROUPS` (the
    ``cuboids`` program imports this module only when the group is used)."""
    return typer.main.get_group(train_app)


#: The output folder of ``cuboids train solver`` by default.
OUTPUT = "runs/solver"

#: The end of ``cuboids train solver``'s torchrun paragraph.
SOLVER_PROCESSES = """\
or torchrun ... $(which cuboids) train solver ... (the console script is a Python file);
multi-node: --nnodes N --node_rank R --rdzv_endpoint HOST:PORT instead of --standalone. Each process
draws --batch sets per step, so a step sees --batch x processes sets; --iters and the lr schedule
count steps. Process 0 alone validates, prints and writes OUT, which must be shared for --resume."""


@train_app.command("solver")
@opt.trains(SolverTrainConfig, SolverNetConfig)
@opt.multi_process(f"solver --output {OUTPUT}", then=SOLVER_PROCESSES)
def solver(
    iters: int = opt.train_option(SolverTrainConfig, "iters"),
    batch: int = opt.train_option(SolverTrainConfig, "batch"),
    lr: float = opt.lr_option(SolverTrainConfig),
    width: int = opt.channels_option(SolverNetConfig),
    layers: int = opt.train_option(SolverNetConfig, "layers"),
    heads: int = opt.train_option(SolverNetConfig, "heads", text="Attention heads; must divide --channels."),
    ff: int = opt.train_option(SolverNetConfig, "ff"),
    out_dir: Path = opt.output_option(OUTPUT),
    resume: Path | None = opt.resume_option(
        "or a step_*.pt snapshot, exactly; schedule, data and net shape are taken from it."
    ),
    seed: int = opt.seed_option(SolverTrainConfig),
    threads: int = opt.threads_option(SolverTrainConfig),
    device: str = opt.train_device_option(SolverTrainConfig),
    max_minutes: float | None = opt.max_minutes_option(SolverTrainConfig),
    val_every: int = opt.train_option(SolverTrainConfig, "val_every"),
    backend: str | None = opt.backend_option(),
    old_width: int | None = opt.old_channels_option(),
    old_out: Path | None = opt.old_output_option(),
) -> None:
    """Pre-train the neural cuboid solver on synthetic boxes; best weights go to OUT/best.pt.

    The same weights are in OUT/solver_v2.pt, the name 'cuboids fit --solver neural --weights OUT' reads.
    """
    out_dir = opt.output_folder(out_dir, old_out, OUTPUT)
    width = opt.channels(width, old_width, SolverNetConfig)
    options = dict(locals())
    from cuboidcli.learn.distributed import launched_rank
    from cuboidcli.learn.solver_train import train_solver

    for name, value in (
        ("--iters", iters),
        ("--batch", batch),
        ("--channels", width),
        ("--layers", layers),
        ("--heads", heads),
        ("--ff", ff),
        ("--threads", threads),
        ("--val-every", val_every),
    ):
        if value < 1:
            fail(f"{name} must be at least 1 (got {value})")
    if width % heads:
        fail(f"--channels {width} is not divisible by --heads {heads}; pick e.g. --heads 4")
    if lr <= 0:
        fail(f"--lr must be positive (got {lr})")
    if resume is not None and not resume.is_file():
        fail(f"--resume {resume}: no such file; pass {out_dir / 'last.pt'} or a step_*.pt checkpoint")
    cfg = opt.config_of(
        SolverTrainConfig,
        options,
        warmup=min(500, max(1, iters // 20)),
        device=resolve_device(device),
        ckpt_every=val_every,
    )
    net_cfg = opt.config_of(SolverNetConfig, options)

    # Under torchrun only rank 0 reports; the others would draw duplicate progress bars.
    main_rank = launched_rank() == 0
    progress = progress_bar(
        "[bold]{task.description}",
        "{task.fields[status]}",
        TimeElapsedColumn(),
        TimeRemainingColumn(),
        disable=not main_rank,
    )
    with training_run(out_dir, resume, first_save="the first checkpoint (--val-every steps)"):
        task = None  # the bar is shown once training starts: a refused run prints its error only

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
from cuboidcli.cli import train_seed as _train_seed  # noqa: E402

_train_seed.register(train_app)

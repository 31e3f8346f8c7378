"""``cuboids train depth``: train the built-in monocular depth network on an RGB-D dataset folder.

Registered on the ``train`` sub-command group by :func:`register`; the training itself lives in
:mod:`cuboidcli.learn.depth_train`.
"""

from __future__ import annotations

import json
import math
from pathlib import Path

import typer

from cuboidcli.cli import train_options as opt
from cuboidcli.cli.common import check_training_paths, console, fail, resolve_device, training_run
from cuboidcli.learn.depth_train import DepthTrainConfig

_DEFAULTS_NOTE = "With --resume: the checkpoint's."
#: The output folder by default.
OUTPUT = "runs/depth"


def _say(text: str, style: str | None = None) -> None:
    """One line on stderr, never wrapped (logs stay one record a line), with no markup parsed in ``text``."""
    console.print(text, style=style, markup=False, highlight=False, soft_wrap=True)


def _duration(seconds: float) -> str:
    return f"{seconds:.0f} s" if seconds < 90 else f"{seconds / 60:.1f} min"


class _EventPrinter:
    """Prints the trainer's records (``on_event`` of :func:`~cuboidcli.learn.depth_train.train_depth`), one
    line each; remembers the run's length from the ``start`` record."""

    def __init__(self, header: str = "") -> None:
        self.header = header
        """Printed with the ``start`` record (a run refused before it starts prints only its error)."""
        self.epochs = 0
        self.steps = 0

    def __call__(self, record: dict) -> None:
        kind = record.get("event")
        if kind == "start":
            if self.header:
                _say(self.header)
            self.epochs = record["epochs"]
            self.steps = record["epochs"] * record.get("steps_per_epoch", 0)
            where = f" on {record['device']}" if "device" in record else ""
            frames = ""
            if "train_frames" in record:
                frames = f"{record['train_frames']} train / {record['val_frames']} val frames, "
            _say(
                f"depth net: {record['parameters']:,} parameters; {frames}batch {record.get('batch', '?')}; "
                f"epoch {record['epoch']} -> {record['epochs']}{where}"
            )
            if record["epoch"] >= record["epochs"]:
                _say(
                    f"the checkpoint has done all {record['epochs']} epochs; give a larger --epochs to go on",
                    style="yellow",
                )
        elif kind == "train":
            steps = f"/{self.steps}" if self.steps else ""
            speed = f", {record['images_per_s']:.1f} images/s" if "images_per_s" in record else ""
            _say(
                f"epoch {record['epoch'] + 1}/{self.epochs} step {record['step']}{steps}: "
                f"loss {record['loss']:.4f}, lr {record['lr']:.2e}, grad norm {record['grad_norm']:.2f}"
                f"{speed} ({_duration(record['elapsed_s'])})"
            )
        elif kind == "val":
            tag = " *best*" if record.get("best") else ""
            _say(
                f"val epoch {record['epoch']}/{self.epochs}: AbsRel {record['abs_rel']:.4f}, "
                f"RMSE {record['rmse_m']:.3f} m, delta<1.25 {record['delta1']:.3f} "
                f"({record['frames']} frames){tag} ({_duration(record['elapsed_s'])})",
                style="bold",
            )
        elif kind == "done":
            best = record["best_abs_rel"]
            note = " (stopped by --max-minutes)" if record.get("timed_out") else ""
            _say(
                f"done: epoch {record['epoch']}, step {record['step']}{note} in "
                f"{_duration(record['elapsed_s'])}; best val AbsRel "
                f"{f'{best:.4f}' if math.isfinite(best) else 'n/a'}; weights {record['best']}; "
                f"training state {record['last']}",
                style="green",
            )


@opt.trains(DepthTrainConfig)
def train_depth_cmd(
    ctx: typer.Context,
    data: Path = typer.Argument(
        ..., help="RGB-D dataset folder (the layout of 'cuboids synth'; splits.json gives train/val)."
    ),
    epochs: int = opt.epochs_option(
        DepthTrainConfig,
        more="With --resume: the checkpoint's unless given (a larger value extends a run and stretches "
        "its lr decay).",
    ),
    batch: int = opt.train_option(DepthTrainConfig, "batch", more=_DEFAULTS_NOTE),
    lr: float = opt.lr_option(DepthTrainConfig, more=_DEFAULTS_NOTE),
    l1_weight: float = opt.train_option(DepthTrainConfig, "l1_weight", more=_DEFAULTS_NOTE),
    min_crop: float = opt.train_option(DepthTrainConfig, "min_crop", more=_DEFAULTS_NOTE),
    jitter: float = opt.train_option(DepthTrainConfig, "jitter", more=_DEFAULTS_NOTE),
    white_balance: float = opt.train_option(DepthTrainConfig, "white_balance", more=_DEFAULTS_NOTE),
    blur: float = opt.train_option(DepthTrainConfig, "blur", more=_DEFAULTS_NOTE),
    noise: float = opt.train_option(DepthTrainConfig, "noise", more=_DEFAULTS_NOTE),
    grad_weight: float = opt.train_option(DepthTrainConfig, "grad_weight", more=_DEFAULTS_NOTE),
    init: str | None = opt.train_option(DepthTrainConfig, "init", more="Ignored with --resume."),
    log_every: int = opt.train_option(DepthTrainConfig, "log_every"),
    out: Path = opt.output_option(OUTPUT),
    resume: Path | None = opt.resume_option("net, schedule and augmentation come from it."),
    seed: int = opt.seed_option(DepthTrainConfig, more=_DEFAULTS_NOTE),
    threads: int = opt.threads_option(DepthTrainConfig),
    device: str = opt.train_device_option(DepthTrainConfig),
    max_minutes: float | None = opt.max_minutes_option(
        DepthTrainConfig, more="With --resume: the checkpoint's unless given."
    ),
    json_lines: bool = typer.Option(
        False, "--json", help="Print the training records as JSON lines on stdout instead of progress lines."
    ),
    old_out: Path | None = opt.old_output_option(),
) -> None:
    """Train the built-in depth network on DATA; the best weights (lowest val AbsRel) go to OUT/best.pt.

    Images are resized to the net's 320x240 input; OUT also gets config.json, log.jsonl and last.pt.
    Use the weights with: cuboids fit IMAGE --depth-model OUT/best.pt ...
    """
    out = opt.output_folder(out, old_out, OUTPUT)
    options = dict(locals())
    from cuboidcli.learn.depth_train import RESUME_OVERRIDES, train_depth

    check_training_paths(data, resume, out)
    if init is not None and resume is None and not Path(init).is_file():
        fail(f"--init {init}: no such weights file (give a depth network's .pt, e.g. models/depth_v4.pt)")
    if resume is None and (out / "last.pt").is_file():
        fail(
            f"--output {out} already holds a training run; continue it with --resume {out / 'last.pt'} "
            "or pick another --output"
        )
    cfg = opt.config_of(DepthTrainConfig, options, device=resolve_device(device))

    def given(name: str) -> bool:  # by name: typer may bring its own copy of click's ParameterSource
        source = ctx.get_parameter_source(name)
        return source is not None and source.name not in ("DEFAULT", "DEFAULT_MAP")

    overrides = set(RESUME_OVERRIDES) - {"max_minutes"}
    if resume is not None:
        overrides |= {name for name in ("epochs", "max_minutes") if given(name)}
        fixed = (
            *("batch", "lr", "l1_weight", "min_crop", "jitter", "white_balance", "blur", "noise"),
            *("grad_weight", "init", "seed"),
        )
        ignored = [name for name in fixed if given(name)]
        if ignored:
            options = ", ".join("--" + name.replace("_", "-") for name in ignored)
            _say(f"warning: {options}: ignored with --resume (the checkpoint's values apply)", style="yellow")
    printer = _EventPrinter(f"training the depth net on {data}; logs and checkpoints in {out}")
    if json_lines:
        printer = _print_json  # type: ignore[assignment]
    with training_run(out, resume):
        train_depth(data, out, cfg, resume=resume, on_event=printer, resume_overrides=overrides)


def _print_json(record: dict) -> None:
    typer.echo(json.dumps(record))


def register(train_app: typer.Typer) -> None:
    """Add the ``depth`` command to the ``cuboids train`` group."""
    train_app.command("depth")(train_depth_cmd)

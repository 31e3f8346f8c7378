"""The options of the ``cuboids train`` commands, defined once from the training configs.

An option named after a field of a training config (SamplerTrainConfig, SolverNetConfig, ...) takes the
field's default and, as help, the first paragraph of its docstring (:func:`train_option`, as
:mod:`cuboidcli.cli.options` does for FitConfig); the options every trainer has (``--output``, ``--seed``,
``--device``, ...) are one function each; :func:`config_of` turns a command's options into a config.
``tests/cli/test_train_options.py`` holds the training commands to this. A module of its own, so that
the modules of ``cuboids fit`` (cli/fit.py, cli/options.py) do not depend on the training package; the
``cuboids`` program still imports it when it registers the train commands.
"""

from __future__ import annotations

import dataclasses
import inspect
from pathlib import Path

import typer
from rich.markup import escape

from cuboidcli.cli.common import fail
from cuboidcli.cli.options import field_help
from cuboidcli.cli.renamed import renamed_option, renamed_value
from cuboidcli.learn.run_config import RunConfig


def field_default(cls: type, name: str):
    """The default of field ``name`` of dataclass ``cls``."""
    field = {f.name: f for f in dataclasses.fields(cls)}[name]
    return field.default if field.default_factory is dataclasses.MISSING else field.default_factory()


def train_option(
    cls: type,
    name: str,
    *flag_names: str,
    doc: type | None = None,
    text: str | None = None,
    more: str = "",
    show_default: bool | str = True,
):
    """The option of a ``cuboids train`` command that sets field ``name`` of the training config ``cls``:
    its flags (``flag_names``; by default ``--`` + the name with dashes), the field's default, and as help
    the first paragraph of the field's docstring (of the same field of ``doc`` where given; ``text``
    instead where given), with ``more`` appended."""
    flag_names = flag_names or (f"--{name.replace('_', '-')}",)
    help_text = text if text is not None else field_help(name, doc or cls)
    return typer.Option(
        field_default(cls, name),
        *flag_names,
        help=escape(help_text + (f" {more}" if more else "")),
        show_default=show_default,
    )


def trains(*configs: type):
    """Decorator of a ``cuboids train`` command: the config dataclasses its options set fields of (an option
    named after a field has the field's default; tests/cli/test_train_options.py checks it)."""

    def mark(command):
        command.configs = configs
        return command

    return mark


def config_of(cls: type, options: dict, **given):
    """Dataclass ``cls`` made from a command's options (its parameters by name): every field an option is
    named after is set from it, ``given`` ones from ``given``; the others keep their defaults. A value the
    dataclass refuses (ValueError) ends the command with its message (:func:`fail`)."""
    names = {f.name for f in dataclasses.fields(cls) if f.init}
    try:
        return cls(**{**{k: v for k, v in options.items() if k in names}, **given})
    except ValueError as e:
        fail(str(e))


#: The end of the torchrun paragraph of a data-parallel trainer's help (:func:`multi_process`).
SPLIT_BATCHES = """\
The --batch scenes of a step are split over the processes (use a multiple of their number), each
process drawing its own hypotheses, and the gradients averaged; the val frames are split too.
Process 0 alone prints and writes OUT, which must be shared for --resume; resuming with the same
number of processes continues the run exactly."""


def multi_process(arguments: str, per: str = "GPU or per group of CPU cores", then: str = SPLIT_BATCHES):
    """Decorator of a ``cuboids train`` command that runs under torchrun: appends to its help (docstring) the
    paragraph on that, with the command line ``train ARGUMENTS``, what a process runs on (``per``) and
    ``then``, the text after the command line."""

    def add(command):
        command.__doc__ = (
            f"{inspect.cleandoc(command.__doc__ or '')}\n\n"
            f"Multi-process (data parallel, one process per {per}), e.g. 2 processes:\n\n"
            f"    torchrun --standalone --nproc_per_node 2 -m cuboidcli.cli.main train {arguments}\n\n{then}"
        )
        return command

    return add


def output_option(default: str):
    """The output folder (``--output``/``-o``; ``--out`` is its old spelling: :func:`old_output_option`)."""
    return typer.Option(Path(default), "--output", "-o", help="Output folder: logs, checkpoints and weights.")


def old_output_option():
    return renamed_option("--out", "--output")


def output_folder(output: Path, old: Path | None, default: str) -> Path:
    """The output folder a command was given: ``--output``, else ``--out`` (with a warning)."""
    return renamed_value(output, Path(default), old, "--out", "--output")


def channels_option(cls: type, doc: type | None = None):
    """The network's width in channels, field ``width`` of ``cls`` (``--width`` is its old spelling:
    :func:`old_channels_option`; ``cuboids synth --width`` is an image width)."""
    return train_option(cls, "width", "--channels", doc=doc)


def old_channels_option():
    return renamed_option("--width", "--channels")


def channels(width: int, old: int | None, cls: type) -> int:
    """The channels a command was given: ``--channels``, else ``--width`` (with a warning)."""
    return renamed_value(width, field_default(cls, "width"), old, "--width", "--channels")


def resume_option(more: str = ""):
    return typer.Option(
        None,
        "--resume",
        help=escape(
            "Continue a run from the training state it saved (OUT/last.pt)" + (f" {more}" if more else ".")
        ),
    )


def seed_option(cls: type, more: str = ""):
    return train_option(cls, "seed", more=more)


def threads_option(cls: type):
    return train_option(cls, "threads", text="torch CPU threads (the machine's cores may be shared).")


def train_device_option(cls: type):
    return train_option(cls, "device", text="auto, cpu or cuda.")


def epochs_option(cls: type, more: str = ""):
    return train_option(cls, "epochs", more=more)


def lr_option(cls: type, more: str = ""):
    return train_option(cls, "lr", more=more)


def max_minutes_option(cls: type, more: str = ""):
    return train_option(cls, "max_minutes", more=more)


def workers_option(cls: type):
    return train_option(cls, "workers", "--workers", "-j", text="Threads reading and preparing the frames.")


def scenes_per_epoch_option(cls: type):
    return train_option(
        cls, "scenes_per_epoch", text="Scenes per epoch.", show_default="every training frame once"
    )


def val_hypotheses_option(cls: type):
    return train_option(cls, "val_hypotheses", text="|H| when fitting the val frames.")


def val_frames_option(cls: type):
    return train_option(cls, "val_frames", text="Validate on at most this many frames.", show_default="all")


def backend_option():
    return typer.Option(
        field_default(RunConfig, "backend"),
        "--backend",
        help="torch.distributed backend under torchrun: gloo or nccl.",
        show_default="nccl on CUDA, gloo on the CPU",
    )

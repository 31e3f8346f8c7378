"""Command-line options that set :class:`~cuboidcli.fitting.config.FitConfig` fields, defined once.

Such an option is the parameter of its command named after the field (``slab_max_m``; :func:`flags` gives
its flags, ``--slab-max``); its default is the field's and its help text the first paragraph of the field's
docstring in fitting/config.py (:func:`field_help`). :func:`fit_config` turns a command's options into a
FitConfig, with the command line's checks and messages. ``--fast`` and ``--device``, which are no plain
fields, are defined here once for every command. ``tests/cli/test_options.py`` holds the commands to this.

The ``cuboids train`` commands' options are defined here the same way (:func:`train_option`): an option
named after a field of a training config (SamplerTrainConfig, SolverNetConfig, ...) takes the field's
default and docstring; the options every trainer has (``--out``, ``--seed``, ``--device``, ...) are one
function each. ``tests/cli/test_train_options.py`` holds the training commands to this.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import sys
from functools import cache
from pathlib import Path

import typer
from rich.markup import escape

from cuboidcli.api import SAMPLERS, SOLVERS, Fitter
from cuboidcli.cli.common import fail, resolve_device
from cuboidcli.fitting.config import ALIGN_MODES, FitConfig
from cuboidcli.learn.trainer import RunConfig

FIELDS = tuple(f.name for f in dataclasses.fields(FitConfig))
DEFAULTS = FitConfig()
#: Flags whose name is not the field's (``--`` + the field name with dashes, else).
FLAG_NAMES = {"occlusion_aware": "oai", "slab_max_m": "slab-max", "gravity_down": "gravity"}
#: ``--fast``: every hypothesis is scored on this many points first (FitConfig.prescore_points).
FAST_PRESCORE_POINTS = 600
#: ``--device``: the Python API's default (auto: cuda where there is one); FitConfig.device is the result.
DEVICE_DEFAULT = inspect.signature(Fitter).parameters["device"].default


@cache
def field_docs(cls: type = FitConfig) -> dict[str, str]:
    """The docstring of every field of dataclass ``cls`` (the string after the field in its class body),
    dedented: FitConfig's by default, or a training config's. Fields declared in a base class have the
    base's docstring unless ``cls`` (or a nearer base) declares them again with one of its own."""
    docs = {}
    for klass in reversed(cls.__mro__):
        if dataclasses.is_dataclass(klass):
            docs.update(_own_field_docs(klass))
    return docs


def _own_field_docs(cls: type) -> dict[str, str]:
    """The field docstrings written in ``cls``'s own class body."""
    tree = ast.parse(inspect.getsource(sys.modules[cls.__module__]))
    body = next(
        node for node in ast.walk(tree) if isinstance(node, ast.ClassDef) and node.name == cls.__name__
    )
    docs = {}
    for node, after in zip(body.body, body.body[1:], strict=False):
        if (
            isinstance(node, ast.AnnAssign)
            and isinstance(node.target, ast.Name)
            and isinstance(after, ast.Expr)
            and isinstance(after.value, ast.Constant)
            and isinstance(after.value.value, str)
        ):
            docs[node.target.id] = inspect.cleandoc(after.value.value)
    return docs


def field_summary(name: str, cls: type = FitConfig) -> str:
    """The first paragraph of field ``name``'s docstring on one line, its ``literals`` as written."""
    return " ".join(field_docs(cls)[name].split("\n\n", 1)[0].split())


def field_help(name: str, cls: type = FitConfig) -> str:
    """The help text of the option that sets field ``name``: :func:`field_summary` without literal marks."""
    return field_summary(name, cls).replace("``", "")


def flags(name: str) -> str:
    """The flags of the option that sets field ``name``: ``--grid-step``; ``--refine/--no-refine`` for a
    switch."""
    flag = FLAG_NAMES.get(name, name.replace("_", "-"))
    return f"--{flag}/--no-{flag}" if isinstance(getattr(DEFAULTS, name), bool) else f"--{flag}"


def shown_default(name: str) -> str:
    """Field ``name``'s default as the help shows it: the value, or the flag a switch is on by default."""
    value = getattr(DEFAULTS, name)
    if isinstance(value, bool):
        on, off = flags(name).split("/")
        return (on if value else off).removeprefix("--")
    return str(value)


def config_option(name: str, *short: str, show_default: bool | str = True, more: str = ""):
    """The option that sets FitConfig field ``name``: its flags (:func:`flags`, plus ``short`` ones such as
    ``-n``), the field's default, and the field's help text; ``more`` is appended to that where the command
    line differs (the format of a value given as text)."""
    return typer.Option(
        getattr(DEFAULTS, name), flags(name), *short, help=_help(name, more), show_default=show_default
    )


def _help(name: str, more: str) -> str:
    # Escaped: typer reads help text as rich markup, where "[default: 4]" would vanish as an unknown tag.
    return escape(field_help(name) + (f" {more}" if more else ""))


def override_option(name: str, *short: str, of: str, more: str = ""):
    """The option that sets FitConfig field ``name`` in a config made elsewhere (``of``: "the preset's"):
    None when not given, so that that value stands; the default shown says both. Help as
    :func:`config_option`."""
    return typer.Option(
        None, flags(name), *short, help=_help(name, more), show_default=f"{shown_default(name)}, or {of}"
    )


def fast_option():
    return typer.Option(
        False,
        "--fast",
        help=f"Approximate scoring: rank hypotheses on {FAST_PRESCORE_POINTS} points first and rescore the "
        f"best {DEFAULTS.rescore_top} on all points.",
    )


def device_option():
    return typer.Option(DEVICE_DEFAULT, "--device", help="auto | cpu | cuda.")


# The options of the cuboids train commands.


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


def out_option(default: str):
    return typer.Option(Path(default), "--out", "-o", help="Output folder: logs, checkpoints and weights.")


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


def fit_config(options: dict, base: FitConfig | None = None, samplers=SAMPLERS, solvers=SOLVERS) -> FitConfig:
    """The FitConfig of a command's options (its parameters by name): ``base`` (default: FitConfig's
    defaults) with each option named after a field that is given (not None) set, checked as the command
    line checks them (one-line errors naming the flag, exit status 2). ``--gravity`` text is parsed,
    ``fast`` sets prescore_points, ``device`` (auto) is resolved; other options are ignored."""
    settings = {name: options[name] for name in FIELDS if options.get(name) is not None}
    for name, value in settings.items():
        _check(name, value, samplers, solvers)
    if "gravity_down" in settings:
        settings["gravity_down"] = parse_gravity(settings["gravity_down"])
    if "device" in settings:
        settings["device"] = resolve_device(settings["device"])
    if options.get("fast"):
        settings["prescore_points"] = FAST_PRESCORE_POINTS
    return dataclasses.replace(base or DEFAULTS, **settings)


def _check(name: str, value, samplers, solvers) -> None:
    flag = flags(name).split("/")[0]
    if name in ("hypotheses", "max_cuboids", "grid_step", "max_batches") and value < 1:
        fail(f"{flag} must be at least 1 (got {value})")
    if name == "local_fraction" and not 0.0 <= value <= 1.0:
        fail(f"{flag} must be between 0 and 1 (got {value})")
    if name == "slab_max_m" and value <= 0:
        fail(f"{flag} must be positive metres (got {value})")
    if name == "align" and value not in ALIGN_MODES:
        fail(f"{flag} {value!r}: choose {', '.join(ALIGN_MODES)}")
    for field, choices in (("sampler", samplers), ("solver", solvers)):
        if name == field and value not in choices:
            fail(f"{flag} {value!r}: choose {', '.join(choices[:-1])} or {choices[-1]}")


def parse_gravity(text: str) -> tuple[float, float, float]:
    """``--gravity gx,gy,gz`` (the down direction in camera coordinates; any length) or a sensor
    convention: ``y-down`` (a level OpenCV camera: 0,1,0)."""
    conventions = {"y-down": (0.0, 1.0, 0.0), "level": (0.0, 1.0, 0.0)}
    if text.strip().lower() in conventions:
        return conventions[text.strip().lower()]
    try:
        v = tuple(float(x) for x in text.split(","))
    except ValueError:
        v = ()
    if len(v) != 3 or not all(math.isfinite(x) for x in v) or not any(v):
        fail(
            f"--gravity {text!r}: give the down direction in camera coordinates as gx,gy,gz "
            "(e.g. 0,1,0 for a level camera; from an IMU or ARKit) or 'level'"
        )
    return v


def option_defaults(command) -> dict:
    """The value of every parameter of a command's function when its option is not given."""
    params = inspect.signature(command).parameters
    return {name: getattr(p.default, "default", p.default) for name, p in params.items()}


def call_with_defaults(command, **given):
    """Call a command's function as the command line does when only ``given`` is set: every other
    parameter takes its option's default (``cuboids demo`` is ``cuboids fit`` with a few options)."""
    return command(**{**option_defaults(command), **given})

"""Command-line options that set :class:`~cuboidcli.fitting.config.FitConfig` fields, defined once.

Such an option is the parameter of its command named after the field (``slab_max_m``; :func:`flags` gives
its flags, ``--slab-max``); its default is the field's and its help text the first paragraph of the field's
docstring in fitting/config.py (:func:`field_help`). :func:`fit_config` turns a command's options into a
FitConfig, checked by FitConfig's own checks with the flags named in their messages. ``--fast`` and
``--device``, which are no plain fields, are defined here once for every command.
``tests/cli/test_options.py`` holds the commands to this.

The ``cuboids train`` commands' options are made the same way from the training configs:
:mod:`cuboidcli.cli.train_options`.
"""

from __future__ import annotations

import ast
import dataclasses
import inspect
import math
import sys
from functools import cache

import typer
from rich.markup import escape

from cuboidcli.api import Fitter
from cuboidcli.cli.common import fail, resolve_device
from cuboidcli.fitting import parts
from cuboidcli.fitting.config import KIND_DEFAULTS, FitConfig, setting_error
from cuboidcli.fitting.parts import SAMPLERS, SOLVERS

FIELDS = tuple(f.name for f in dataclasses.fields(FitConfig))
DEFAULTS = FitConfig()
#: Flags whose name is not the field's (``--`` + the field name with dashes, else).
FLAG_NAMES = {
    "occlusion_aware": "oai",
    "slab_max_m": "slab-max",
    "gravity_down": "gravity",
    "voxel_m": "voxel",
}
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
    """The first paragraph of field ``name``'s docstring on one line, its ``literals`` as written; for the
    fields that name a sampler or a solver, followed by the registered ones (:func:`parts.describe`)."""
    text = " ".join(field_docs(cls)[name].split("\n\n", 1)[0].split())
    if cls is FitConfig and name in parts.ROLES:
        text = f"{text}: {parts.describe(name)}."
    return text


def field_help(name: str, cls: type = FitConfig) -> str:
    """The help text of the option that sets field ``name``: :func:`field_summary` without literal marks."""
    return field_summary(name, cls).replace("``", "")


def flags(name: str) -> str:
    """The flags of the option that sets field ``name``: ``--grid-step``; ``--refine/--no-refine`` for a
    switch."""
    flag = FLAG_NAMES.get(name, name.replace("_", "-"))
    return f"--{flag}/--no-{flag}" if isinstance(getattr(DEFAULTS, name), bool) else f"--{flag}"


def shown_default(name: str) -> str:
    """Field ``name``'s default as the help shows it: the value, the flag a switch is on by default, or for
    a setting whose default depends on the input, a frame's and a room's (``8; a room: 60``)."""
    value = getattr(DEFAULTS, name)
    if value is None and name in KIND_DEFAULTS["frame"]:
        return f"{KIND_DEFAULTS['frame'][name]}; a room: {KIND_DEFAULTS['room'][name]}"
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


def fit_config(options: dict, base: FitConfig | None = None, samplers=SAMPLERS, solvers=SOLVERS) -> FitConfig:
    """The FitConfig of a command's options (its parameters by name): ``base`` (default: FitConfig's
    defaults) with each option named after a field that is given (not None) set, each checked by
    FitConfig's check of that field (:func:`~cuboidcli.fitting.config.setting_error`: one-line errors
    naming the flag, exit status 2). ``samplers`` and ``solvers``: the parts the command offers (default:
    every registered one). ``--gravity`` text is parsed, ``fast`` sets prescore_points, ``device`` (auto) is
    resolved; other options are ignored."""
    settings = {name: options[name] for name in FIELDS if options.get(name) is not None}
    if "gravity_down" in settings:
        settings["gravity_down"] = parse_gravity(settings["gravity_down"])
    if "device" in settings:
        settings["device"] = resolve_device(settings["device"])
    offered = {"sampler": tuple(samplers), "solver": tuple(solvers)}
    for name, value in settings.items():
        error = setting_error(name, value, flags(name).split("/")[0], offered.get(name))
        if error is not None:
            fail(error)
    if options.get("fast"):
        settings["prescore_points"] = FAST_PRESCORE_POINTS
    try:
        return dataclasses.replace(base or DEFAULTS, **settings)
    except ValueError as e:  # a combination the single settings' checks cannot see
        fail(str(e))


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

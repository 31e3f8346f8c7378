"""Every option of every command with its type and valid range, in one table: :data:`OPTIONS` (and, for
the ``cuboids train`` commands, :data:`cuboidcli.cli.train_checks.TRAIN_OPTIONS`).

An option that sets an estimator setting takes that setting's check (:data:`cuboidcli.fitting.config.CHECKS`),
one that says how an input is read the library's (:data:`cuboidcli.fitting.checks.LOAD_CHECKS`), so the
command line and the Python API give the same words; the others have their check here, in the same form.
:func:`check_options` applies the table to a command as it parses its options: a value that is not
allowed (NaN, inf, out of range, empty, not a number) ends the command with one line naming the flag and
what it allows, exit status 2, before anything is read or written. Switches take no value and are not
listed; ``tests/cli/test_option_table.py`` holds every other option of every command to a row here.
"""

from __future__ import annotations

import math

import typer

from cuboidcli.camera import PRESETS as CAMERAS
from cuboidcli.cli.common import fail
from cuboidcli.evaluation.presets import PRESETS as EVAL_PRESETS
from cuboidcli.fitting.checks import DEVICE, LOAD_CHECKS, PATH, Check, choice, text, whole
from cuboidcli.fitting.config import CHECKS

SEED = CHECKS["seed"]
#: Local processes: more than the cores of any one machine is a typo.
WORKERS = whole(1, 1024)


def _numbers(value: str, count: int | None = None) -> list[float]:
    numbers = [float(x) for x in value.split(",")]
    if (count is not None and len(numbers) != count) or not all(map(math.isfinite, numbers)):
        raise ValueError(value)
    return numbers


def _gravity(value: str) -> bool:
    return value.strip().lower() in ("level", "y-down") or any(_numbers(value, 3))


def _up(value: str) -> bool:
    from cuboidcli.load.room import UP_NAMES

    return value.strip().lower() in UP_NAMES or any(_numbers(value, 3))


def _auc(value: str) -> bool:
    return all(x > 0 for x in _numbers(value.replace(" ", "").strip(",")))


def _presets(value: str) -> bool:
    names = [n.strip() for n in value.split(",") if n.strip()]
    return bool(names) and all(n in EVAL_PRESETS for n in names)


def _onnx_presets() -> tuple[str, ...]:
    from cuboidcli.depth.onnx_presets import PRESETS

    return tuple(PRESETS)


def fitting(*names: str) -> dict[str, Check]:
    """The options named after estimator settings: the settings' own checks."""
    return {name: CHECKS[name] for name in names}


FIT: dict[str, Check] = {
    **fitting("hypotheses", "max_cuboids", "sampler", "solver", "seed", "theta", "grid_step"),
    **fitting("local_fraction", "max_batches", "align", "slab_max_m", "visibility", "voxel_m", "object_fits"),
    "device": DEVICE,
    "gravity_down": text("gx,gy,gz (3 finite numbers, not all 0) or level", _gravity),
    "up": text("z, y, -y, x or x,y,z (3 finite numbers, not all 0)", _up),
    **dict.fromkeys(("image", "depth", "output", "weights", "onnx", "partial_depth"), PATH),
    "intrinsics": text("fx,fy,cx,cy in pixels or a JSON file"),
    "camera": choice(CAMERAS),
    "preset": choice(CAMERAS),
    "depth_scale": LOAD_CHECKS["depth_scale"],
    "unit": LOAD_CHECKS["unit"],
    "every": LOAD_CHECKS["every"],
    "depth_model": text("a .pt or .onnx file, a save_pretrained folder or hf:owner/name"),
    "depth_model_kind": LOAD_CHECKS["kind"],
    "relative_scale": LOAD_CHECKS["scale"],
    "relative_shift": LOAD_CHECKS["shift"],
    "camera_height": LOAD_CHECKS["camera_height_m"],
    "onnx_preset": choice(_onnx_presets()),
    "workers": WORKERS,
    "ray_address": text("auto, HOST:PORT or ray://HOST:10001"),
}

#: The command line's tables: command (its words after ``cuboids``; a module's command by its module's
#: name) -> option parameter -> check. Switches are left out (they take no value).
OPTIONS: dict[str, dict[str, Check]] = {
    "fit": FIT,
    "demo": {"output": PATH, "seed": SEED, "device": DEVICE},
    "export": {
        **dict.fromkeys(
            ("result_json", "glb", "ply", "obj", "overlay", "image", "depth", "html", "mjcf", "urdf", "usd"),
            PATH,
        ),
        **dict.fromkeys(("rrd", "onnx", "weights"), PATH),
        "depth_scale": LOAD_CHECKS["depth_scale"],
        "step": whole(1, 10_000),
        "opset": whole(7, 30),
    },
    "evaluate": {
        **fitting("sampler", "solver", "hypotheses", "max_cuboids", "grid_step", "align", "seed"),
        "visibility": CHECKS["visibility"],
        "device": DEVICE,
        **dict.fromkeys(("data", "output", "fits", "weights"), PATH),
        "split": text("a split name (NYU: test, train or val; a folder: one of its splits.json)"),
        "limit": whole(1, 10**9),
        "frames": text("comma-separated frame names", lambda v: any(n.strip() for n in v.split(","))),
        "scans": text("comma-separated scan names", lambda v: any(n.strip() for n in v.split(","))),
        "runs": whole(1, 1000),
        "workers": WORKERS,
        "ray_address": FIT["ray_address"],
        "preset": text(f"presets of {', '.join(EVAL_PRESETS)}, separated by commas", _presets),
        "auc": text("comma-separated positive numbers (cm)", _auc),
        "depth_model": FIT["depth_model"],
    },
    "synth": {
        "out_dir": PATH,
        "count": whole(1, 10**6),
        "seed": SEED,
        "camera": choice(CAMERAS),
        "preset": choice(CAMERAS),
        "width": whole(16, 8192),
        "height": whole(16, 8192),
        "workers": WORKERS,
        "views": whole(1, 10_000),
    },
    "depth_evaluate": {
        **dict.fromkeys(("data", "model", "output", "out"), PATH),
        "split": text("a split name of the folder's splits.json"),
    },
}


def options_of(command: str) -> dict[str, Check]:
    """The table of ``command`` ("fit", "train solver", ...); the training commands' come from their own
    module, which the ``cuboids train`` group imports anyway (its options are the training configs')."""
    if command.startswith("train "):
        from cuboidcli.cli.train_checks import TRAIN_OPTIONS

        return TRAIN_OPTIONS[command]
    return OPTIONS[command]


def flag_of(param) -> str:
    """How the user names a parameter: its first long flag (``--slab-max``), or an argument's name."""
    names = [o for o in getattr(param, "opts", ()) if o.startswith("--")]
    return (
        names[0] if names and getattr(param, "param_type_name", "option") == "option" else param.name.upper()
    )


def check_options(command, name: str):
    """``command`` (a click command or group of ``cuboids``, called ``name``) with every option of its
    table checked as it is parsed (:func:`options_of`): a value its check refuses, or one that is not even
    of the option's type, ends the command with the check's one line (exit status 2). Returns the command;
    a command already checked is left as it is."""
    if getattr(command, "options_checked", False):
        return command
    command.options_checked = True
    if hasattr(command, "commands"):  # a group: each of its commands
        for sub, cmd in command.commands.items():
            check_options(cmd, f"{name} {sub}")
        return command
    table = options_of(name)
    for param in command.params:
        if param.name in table:
            param.process_value = _checked(param.process_value, table[param.name], flag_of(param))
    return command


def _checked(convert, check: Check, flag: str):
    """``convert`` (a parameter's ``process_value``: the text as given -> the value) followed by ``check``;
    either failing ends the command with the check's message."""

    def process_value(ctx, value):
        if check.kind in ("text", "path") and isinstance(value, str) and check.error(flag, value):
            fail(check.error(flag, value))  # the text as given: an empty path would become "."
        try:
            converted = convert(ctx, value)
        except typer.BadParameter:
            error = check.error(flag, value)
            if error is None:  # the check would take the text: the conversion's own message stands
                raise
            fail(error)
        error = check.error(flag, converted)
        if error is not None:
            fail(error)
        return converted

    return process_value


def rows(command: str, params) -> list[tuple[str, str, str, str]]:
    """The table of ``command`` as rows (flag, kind, allowed values, default) for ``params``, the
    command's click parameters: what ``python scripts/option_table.py`` writes to docs/options.md."""
    table = options_of(command)
    out = []
    for param in params:
        if param.name in table and not getattr(param, "hidden", False):  # an old spelling is not shown
            check = table[param.name]
            default = getattr(param, "default", None)
            out.append((flag_of(param), check.kind, check.range, "" if default is None else str(default)))
    return out

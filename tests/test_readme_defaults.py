"""Every default README.md states is the code's: the option tables under "Settings" (the main options of
``cuboids fit`` and those only a room takes) against the command's options and the estimator's config
(FitConfig, with a frame's and a room's defaults), and the few defaults its prose names. A default changed
in the code without the README, or the other way round, fails here."""

from __future__ import annotations

import inspect
import re
from pathlib import Path

import click
import pytest
import typer

from cuboidcli.fitting.config import KIND_DEFAULTS, FitConfig

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / "README.md"
FIT, ROOM = ("option", "default", "meaning"), ("room option", "default", "meaning")
#: Room options and the FitConfig field each sets, at a room's default (the others are plain options of the
#: fit command).
ROOM_FIELDS = {
    "--max-cuboids": "max_cuboids",
    "--voxel": "voxel_m",
    "--visibility": "visibility",
    "--up": "up",
}


def cells(row: str) -> list[str]:
    """The cells of a markdown table row (escaped pipes ``\\|`` stay inside their cell)."""
    parts = re.split(r"(?<!\\)\|", row.strip().strip("|"))
    return [p.strip().replace("\\|", "|") for p in parts]


def tables(text: str) -> dict[tuple[str, ...], list[list[str]]]:
    """Every markdown table of ``text`` by its header cells (lower case): its body rows' cells."""
    found: dict[tuple[str, ...], list[list[str]]] = {}
    lines = text.splitlines()
    for i, line in enumerate(lines[:-1]):
        if line.startswith("|") and re.fullmatch(r"\|(\s*:?-+:?\s*\|)+", lines[i + 1].strip()):
            body = []
            for row in lines[i + 2 :]:
                if not row.startswith("|"):
                    break
                body.append(cells(row))
            found[tuple(c.lower() for c in cells(line))] = body
    return found


def settings(header: tuple[str, ...]) -> dict[str, str]:
    """{first flag: the default the README states} of the README table with this header."""
    rows = tables(README.read_text(encoding="utf-8")).get(header)
    assert rows, f"README.md has no table headed {' | '.join(header)}"
    return {row[0].strip("`").split("/")[0]: row[1] for row in rows}


def fit_params() -> dict[str, click.Parameter]:
    """The options of ``cuboids fit`` by each of their flags."""
    from cuboidcli.cli.main import app

    group = typer.main.get_command(app)
    command = group.get_command(click.Context(group), "fit")
    return {flag: p for p in command.params for flag in [*p.opts, *p.secondary_opts]}


def shown(param: click.Parameter) -> str:
    """An option's default as a reader of the README expects it: the text its help shows, the flag a switch
    is on by default, on/off for a flag, '-' for none."""
    if isinstance(param.show_default, str):
        return param.show_default.strip("()")
    if param.is_flag and param.secondary_opts:
        return param.opts[0] if param.default else param.secondary_opts[0]
    if param.is_flag:
        return "on" if param.default else "off"
    return "-" if param.default is None else str(param.default)


def test_the_fit_table_states_the_commands_defaults():
    stated, params = settings(FIT), fit_params()
    assert len(stated) >= 15
    for flag, default in stated.items():
        assert flag in params, f"README names {flag}, which cuboids fit does not have"
        assert default.strip("`") == shown(params[flag]), flag


def test_the_fit_tables_defaults_are_the_estimators():
    """The options that set FitConfig fields default to the fields' values (a frame's and a room's, for a
    setting whose default depends on the input), and the computed defaults are stated as the config computes
    them."""
    stated, params, config = settings(FIT), fit_params(), FitConfig().for_kind("frame")
    checked = 0
    for flag, default in stated.items():
        name = params[flag].name
        if not hasattr(config, name):
            continue
        value = getattr(config, name)
        if name == "device":  # FitConfig holds the resolved device; the API's and the command's is auto
            from cuboidcli.api import Fitter

            assert default == inspect.signature(Fitter).parameters["device"].default == "auto"
        elif name == "theta":
            assert value is None and default == f"{config.theta_log_factor:g} ln n"
        elif name == "grid_step":
            assert value is None and f"about {config.fit_points} points" in default
        elif name == "gravity_down":
            assert value is None and default == "estimated"
        elif name in KIND_DEFAULTS["frame"]:  # None on the command line: the input's, a frame's first
            frame, room = (KIND_DEFAULTS[kind][name] for kind in ("frame", "room"))
            assert value == frame and params[flag].default is None, flag
            assert default == f"{frame}; a room: {room}", flag
        elif isinstance(value, bool):
            assert params[flag].default is value and default.strip("`") == shown(params[flag]), flag
        else:
            assert params[flag].default == value and default == str(value), flag
        checked += 1
    assert checked >= 10
    # the two the README's own prose leans on
    assert stated["--sampler"] == config.sampler == "sequential"
    assert stated["--solver"] == config.solver == "numerical"


def test_the_room_table_states_a_rooms_defaults():
    stated, params, scene = settings(ROOM), fit_params(), FitConfig().for_kind("room")
    for flag, default in stated.items():
        assert flag in params, f"README names {flag}, which cuboids fit does not have"
        field = ROOM_FIELDS.get(flag)
        if field is None:
            assert default == shown(params[flag]), flag
        elif getattr(scene, field) is None:
            assert default == "estimated", flag
        else:
            assert default == str(getattr(scene, field)), flag
    assert set(ROOM_FIELDS) <= set(stated)


def prose_claims() -> list[tuple[str, str]]:
    """(text README.md must contain, where the value comes from) for the defaults its prose states."""
    from cuboidcli.io.photo import DEFAULT_FOV_DEG
    from cuboidcli.weights import DEFAULTS

    depth_scale = fit_params()["--depth-scale"].show_default
    return [
        (f"the fitting grid has at most {FitConfig().for_kind('frame').fit_points} points", "KIND_DEFAULTS"),
        (f"{DEFAULT_FOV_DEG:g} degree field of view", "io.photo.DEFAULT_FOV_DEG"),
        (f"`--depth-scale` metres per unit, {depth_scale} by default", "fit --depth-scale"),
        (f"the built-in `models/{DEFAULTS['depth']}`", "weights.DEFAULTS['depth']"),
        (f"at most {FitConfig().for_kind('room').fit_points:,} points remain", "KIND_DEFAULTS"),
    ]


@pytest.mark.parametrize("claim", range(5))
def test_the_prose_states_the_codes_defaults(claim):
    text, source = prose_claims()[claim]
    assert text in " ".join(README.read_text(encoding="utf-8").split()), (
        f"README should say {text!r} ({source})"
    )

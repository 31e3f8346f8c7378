"""Options defined once: the command-line options that set FitConfig fields take their default and help text
from the field (cuboidcli/cli/options.py), and `cuboids fit` and the Python API give the same settings."""

from __future__ import annotations

import dataclasses
import runpy
from pathlib import Path

import click
import pytest
import typer
from rich.markup import escape
from rich.text import Text

import cuboidcli as cb
from cuboidcli.cli.options import (
    FAST_PRESCORE_POINTS,
    field_docs,
    field_help,
    fit_config,
    flags,
    shown_default,
)
from cuboidcli.evaluation.presets import resolve
from cuboidcli.fitting.config import FitConfig

ROOT = Path(__file__).resolve().parents[2]
DEFAULTS = FitConfig()
FIELDS = {f.name for f in dataclasses.fields(FitConfig)}

#: The FitConfig fields each command sets with an option of the field's name.
EXPOSED = {
    "fit": {
        "hypotheses", "max_cuboids", "sampler", "solver", "seed", "device", "theta", "grid_step",
        "occlusion_aware", "refine", "local_fraction", "max_batches", "align", "gravity_down", "slab_max_m",
        "visibility", "up", "voxel_m", "object_fits",
    },
    "evaluate": {
        "sampler", "solver", "hypotheses", "max_cuboids", "grid_step", "occlusion_aware", "refine", "align",
        "seed", "device", "visibility",
    },
    "demo": {"seed", "device"},
}  # fmt: skip
PRESET_OVERRIDES = EXPOSED["evaluate"] - {"seed", "device", "visibility"}

#: (command, field) -> (the CLI default, why it is not the field's default).
OTHER_DEFAULTS = {
    **{
        (command, "device"): (
            "auto",
            "--device is the Python API's device= (Fitter, fit: auto = cuda where there is one); "
            "FitConfig.device holds what auto resolved to",
        )
        for command in ("fit", "evaluate", "demo")
    },
    **{
        ("evaluate", name): (None, "not given: the preset's value stands (without a preset, the field's)")
        for name in PRESET_OVERRIDES
    },
    ("evaluate", "visibility"): (None, "a room scans' option only: not given, the field's auto stands"),
}
#: (command, field) -> why its help text is not the field's doc alone (the doc plus this command's text).
OTHER_HELP = {
    **{(command, "device"): "help of its own: it takes auto, FitConfig.device not" for command in EXPOSED},
    ("fit", "gravity_down"): "the doc plus the format of the text value (gx,gy,gz or 'level')",
    ("evaluate", "sampler"): "the doc plus the samplers an evaluation runs (not local)",
    ("evaluate", "solver"): "the doc plus the solvers an evaluation runs (not onnx: there is no --onnx)",
    ("evaluate", "seed"): "the doc plus: with --runs, the first run's",
    ("evaluate", "visibility"): "help of its own: it applies to room scans only, not to the frames evaluated",
    ("fit", "up"): "the doc plus the names a direction may be given by (z, y, -y, x) or x,y,z",
}


def command(name: str) -> click.Command:
    from cuboidcli.cli.main import app

    group = typer.main.get_command(app)
    return group.get_command(click.Context(group), name)


def commands(group=None, path=()):
    """(path, command) of every command below ``group`` (default: ``cuboids``)."""
    if group is None:
        from cuboidcli.cli.main import app

        group = typer.main.get_command(app)
    for name in group.list_commands(click.Context(group)):
        cmd = group.get_command(click.Context(group), name)
        if hasattr(cmd, "list_commands"):
            yield from commands(cmd, (*path, name))
        else:
            yield (*path, name), cmd


def parse(name: str, args: list[str]) -> dict:
    """The parameters of ``cuboids NAME ARGS`` as the command's function receives them."""
    return command(name).make_context(name, list(args)).params


def test_field_docs_are_read_from_the_config_module():
    docs = field_docs()
    assert set(docs) == FIELDS
    assert field_help("max_cuboids") == "Upper bound on |M|, the number of cuboids returned."
    # The first paragraph is the help text: the details after it are left out, literal marks dropped.
    first, details = docs["hypotheses"].split("\n\n", 1)
    assert field_help("hypotheses") == " ".join(first.replace("``", "").split())
    assert "32 in training" in details and "training" not in field_help("hypotheses")
    assert "``" in docs["align"] and "``" not in field_help("align")
    assert flags("slab_max_m") == "--slab-max" and flags("refine") == "--refine/--no-refine"
    assert flags("occlusion_aware") == "--oai/--no-oai" and shown_default("occlusion_aware") == "oai"


@pytest.mark.parametrize("name", sorted(EXPOSED))
def test_cli_options_take_default_and_help_from_fitconfig(name):
    """Every option named after a FitConfig field has the field's default and, as help, the field's doc
    (its first paragraph); the exceptions are listed above with their reasons."""
    params = {p.name: p for p in command(name).params}
    assert {n for n in params if n in FIELDS} == EXPOSED[name]
    for field in sorted(EXPOSED[name]):
        p = params[field]
        default = OTHER_DEFAULTS.get((name, field), (getattr(DEFAULTS, field), ""))[0]
        assert p.default == default, (name, field)
        if field != "device":
            assert "/".join(p.opts + p.secondary_opts) == flags(field), (name, field)
        doc = escape(field_help(field))
        if (name, field) in OTHER_HELP:
            own = OTHER_HELP[(name, field)].startswith("help of its own")
            assert p.help != doc and (own or p.help.startswith(doc + " ")), (name, field)
        else:
            assert p.help == doc, (name, field)
        if name == "evaluate" and field in PRESET_OVERRIDES:  # the help still shows the field's default
            assert p.show_default == f"{shown_default(field)}, or the preset's", (name, field)
    if name == "fit":  # defaults of None that the help spells out
        assert params["theta"].show_default == f"{DEFAULTS.theta_log_factor:g} ln n" == "6 ln n"
        assert DEFAULTS.theta is None and DEFAULTS.gravity_down is None


def test_fast_sets_the_prescoring_points():
    for name in ("fit", "evaluate"):
        fast = next(p for p in command(name).params if p.name == "fast")
        assert fast.default is False and f"{FAST_PRESCORE_POINTS} points" in fast.help
    assert fit_config({"fast": True}).prescore_points == FAST_PRESCORE_POINTS
    assert fit_config({"fast": False}).prescore_points == DEFAULTS.prescore_points == 0


@pytest.mark.parametrize(
    "args, settings",
    [
        ([], {}),
        (
            "--hypotheses 256 --max-cuboids 5 --seed 3 --theta 40 --grid-step 4 --solver numerical".split(),
            dict(hypotheses=256, max_cuboids=5, seed=3, theta=40.0, grid_step=4, solver="numerical"),
        ),
        (
            "--no-oai --no-refine --fast --align free --local-fraction 0 --max-batches 1 --slab-max 2.5 "
            "--gravity level --sampler uniform".split(),
            dict(
                occlusion_aware=False,
                refine=False,
                prescore_points=FAST_PRESCORE_POINTS,
                align="free",
                local_fraction=0.0,
                max_batches=1,
                slab_max_m=2.5,
                gravity_down=(0.0, 1.0, 0.0),
                sampler="uniform",
            ),
        ),
    ],
)
def test_fit_command_and_api_give_the_same_settings(args, settings):
    """`cuboids fit --depth d.png ARGS` and `cb.Fitter(**settings)` (what `cb.fit` builds) configure the
    estimator alike."""
    options = parse("fit", ["--depth", "d.png", "--device", "cpu", *args])
    assert fit_config(options) == cb.Fitter(device="cpu", **settings).config


def test_evaluate_sets_the_given_options_over_the_presets():
    base = parse("evaluate", ["data", "--device", "cpu"])
    assert fit_config(base) == dataclasses.replace(DEFAULTS, device="cpu")  # no preset: as cuboids fit
    paper, _, _ = resolve("paper")
    options = parse("evaluate", "data --preset paper --no-oai --hypotheses 100 --device cpu --seed 2".split())
    assert fit_config(options, paper) == dataclasses.replace(
        paper, occlusion_aware=False, hypotheses=100, device="cpu", seed=2
    )
    assert fit_config(base, paper) == dataclasses.replace(paper, device="cpu")  # not given: the preset's


def test_no_help_text_is_lost_to_rich_markup():
    """typer renders help text as rich markup, where a "[default: 4]" written into it vanished as an
    unknown tag (--align said "[default: free]", which nobody saw)."""
    seen = 0
    for path, cmd in commands():
        for p in cmd.params:
            if getattr(p, "help", None):
                assert Text.from_markup(p.help).plain == p.help.replace("\\[", "["), (path, p.name)
                seen += 1
    assert seen > 130


def test_readme_option_table_is_written_from_the_command():
    """README.md's table of the main options of cuboids fit is what scripts/readme_options.py writes from
    the command (for the FitConfig options: the fields' defaults and docs)."""
    script = runpy.run_path(str(ROOT / "scripts" / "readme_options.py"))
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    assert script["with_table"](readme) == readme, "out of date: python scripts/readme_options.py"
    table = script["table"]()
    assert "| `--align` | manhattan | Orientation of the selected cuboids: `manhattan` (walls" in table
    assert "| `--theta` | 6 ln n | Theta: " in table and "| `--oai/--no-oai` | `--oai` | " in table

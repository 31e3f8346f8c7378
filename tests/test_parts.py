"""One place for each name: the parts registry (cuboidcli/fitting/parts.py) is what the factories build, the
weights registry loads, the settings' check accepts, and the API and the command line offer."""

from __future__ import annotations

import dataclasses
import importlib

import pytest
from typer.testing import CliRunner

from cuboidcli import api, weights
from cuboidcli.factories import make_sampler, make_solver
from cuboidcli.fitting import parts
from cuboidcli.fitting.config import FitConfig, resolve_device
from cuboidcli.weights import MODELS_DIR

SAMPLERS = [p for p in parts.PARTS if p.role == "sampler"]
SOLVERS = [p for p in parts.PARTS if p.role == "solver"]


def test_one_entry_per_name_and_builders_that_resolve():
    assert len({(p.role, p.name) for p in parts.PARTS}) == len(parts.PARTS)
    assert {p.role for p in parts.PARTS} == set(parts.ROLES)
    home = {"sampler": "cuboidcli.sampling", "solver": "cuboidcli.solvers"}
    for p in parts.PARTS:
        module, _, function = p.builder.partition(":")
        assert callable(getattr(importlib.import_module(module), function)), p
        # a builder lives with its part, below the estimator, not in a layer above it
        assert module == home[p.role] or module.startswith(home[p.role] + "."), p
        assert p.network in (None, *weights.KINDS) and p.help and "\n" not in p.help
    assert parts.SAMPLERS == ("sequential", "learned", "local", "uniform")
    assert parts.SOLVERS == ("numerical", "neural", "onnx")


@pytest.mark.parametrize("part", SAMPLERS, ids=lambda p: p.name)
def test_every_sampler_builds_with_the_shipped_weights(part):
    sampler = make_sampler(part.name, None, "cpu")
    assert sampler.name == part.name
    assert make_sampler(part.name, MODELS_DIR, "cpu").name == part.name  # a --weights folder


@pytest.mark.parametrize("part", [p for p in SOLVERS if p.name != "onnx"], ids=lambda p: p.name)
def test_every_solver_builds_with_the_shipped_weights(part):
    config = FitConfig(solver=part.name)
    assert make_solver(config, None, None, "cpu").name == part.name
    assert make_solver(config, MODELS_DIR / "neural", None, "cpu").name == part.name


def test_the_onnx_solver_builds_from_its_file(tmp_path):
    config = FitConfig(solver="onnx")
    with pytest.raises(ValueError, match="needs an ONNX file"):
        make_solver(config)
    pytest.importorskip("onnxruntime")
    from cuboidcli.solvers.onnx_export import export_solver_onnx

    onnx = export_solver_onnx(MODELS_DIR / "solver_v2.pt", str(tmp_path / "solver.onnx"))
    assert make_solver(config, None, onnx, "cpu").name == "onnx"


def test_unknown_names_are_refused_with_the_registered_ones():
    with pytest.raises(
        ValueError, match="unknown sampler 'best'; choose sequential, learned, local or uniform"
    ):
        make_sampler("best")
    with pytest.raises(ValueError, match=r"unknown solver 'best'; choose numerical, neural or onnx"):
        make_solver(FitConfig(solver="best"))


def test_a_new_part_is_one_line(monkeypatch):
    """A part registered with its builder is built, accepted by the settings' check and loads the weights
    its network kind says, with nothing else to change."""
    mine = parts.Part("sampler", "mine", "cuboidcli.sampling:build_uniform", "sampler", "a test sampler")
    monkeypatch.setattr(parts, "PARTS", (*parts.PARTS, mine))
    assert make_sampler("mine").name == "uniform"
    assert weights.networks_loaded("numerical", "mine") == ["sampler"]
    assert parts.find("sampler", "mine") is mine


def test_the_weights_registry_reads_which_part_loads_a_network():
    assert weights.networks_loaded("neural", "learned") == ["solver", "sampler"]
    assert weights.networks_loaded("numerical", "sequential") == []
    assert weights.networks_loaded("onnx", "local") == []
    assert weights.networks_loaded("bogus", "bogus") == []
    assert weights.default_weights_dir("neural") == MODELS_DIR / "neural"
    assert weights.default_weights_dir("onnx") is None and weights.default_weights_dir("bogus") is None


def test_the_weights_table_gives_every_view():
    assert weights.KINDS == ("sampler", "solver", "depth")
    assert weights.FILES == {"sampler": "sampler_v2.pt", "solver": "solver_v2.pt", "depth": "depth_v2.pt"}
    assert weights.SOLVER_FILES == ("solver_v2.pt", "solver_v1.pt")
    assert weights.DEFAULTS == {"sampler": "sampler_v2.pt", "solver": "solver_v2.pt", "depth": "depth_v4.pt"}
    assert weights.ENV == {k: f"CUBOIDS_{k.upper()}_WEIGHTS" for k in weights.KINDS}
    # `cuboids --version` lists these, in this order
    assert weights.DEFAULT_FILES == (
        ("--sampler learned", "sampler_v2.pt"),
        ("--solver neural", "neural/solver_v2.pt"),
        ("--solver neural (sampler)", "neural/sampler_v2.pt"),
        ("RGB input (depth network)", "depth_v4.pt"),
    )


def test_the_api_and_the_command_line_offer_the_registered_names():
    from cuboidcli.cli import options
    from cuboidcli.cli.main import app

    assert api.SAMPLERS == parts.SAMPLERS and api.SOLVERS == parts.SOLVERS
    defaults = options.fit_config.__defaults__
    assert parts.SAMPLERS in defaults and parts.SOLVERS in defaults
    runner = CliRunner()
    for role, names in (("sampler", parts.SAMPLERS), ("solver", parts.SOLVERS)):
        r = runner.invoke(app, ["fit", "--depth", "d.png", f"--{role}", "best"])
        assert r.exit_code == 2 and f"--{role} 'best': choose {parts.or_list(names)}" in r.output
    with pytest.raises(ValueError, match=f"sampler 'best': choose {parts.or_list(parts.SAMPLERS)}"):
        api.Fitter(sampler="best", device="cpu")


def test_the_help_lists_every_registered_part_with_its_help():
    from cuboidcli.cli.options import field_help, field_summary

    for p in parts.PARTS:
        assert f"``{p.name}`` ({p.help})" in field_summary(p.role), (p.role, p.name)
        assert f"{p.name} ({p.help.replace('``', '')})" in field_help(p.role)
    mine = parts.Part("sampler", "mine", "cuboidcli.sampling:build_uniform", None, "a test sampler")
    with_mine = (*parts.PARTS, mine)
    import unittest.mock

    with unittest.mock.patch.object(parts, "PARTS", with_mine):
        assert field_help("sampler").endswith("mine (a test sampler).")


def test_fitconfig_checks_itself_and_names_the_flag_on_the_command_line():
    with pytest.raises(ValueError, match=r"^hypotheses must be a whole number from 1 to 100000 \(got 0\)$"):
        FitConfig(hypotheses=0)
    with pytest.raises(ValueError, match=r"^local_fraction must be a number from 0 to 1 \(got 2\)$"):
        dataclasses.replace(FitConfig(), local_fraction=2)
    with pytest.raises(ValueError, match=r"^align 'up': choose free, gravity, manhattan$"):
        FitConfig(align="up")
    with pytest.raises(ValueError, match="backend 'numba' runs on the CPU only"):
        FitConfig(backend="numba", device="cuda")
    odd = FitConfig(sampler="mine")  # parts built elsewhere may have any name ...
    with pytest.raises(ValueError, match=r"^sampler 'mine': choose sequential, learned, local or uniform$"):
        odd.check()  # ... but building by name needs a registered one
    FitConfig().check()
    from cuboidcli.cli.main import app

    r = CliRunner().invoke(app, ["fit", "--depth", "d.png", "--max-batches", "0"])
    assert r.exit_code == 2 and "--max-batches must be a whole number from 1 to 1000 (got 0)" in r.output
    r = CliRunner().invoke(app, ["fit", "--depth", "d.png", "--slab-max", "-1"])
    assert r.exit_code == 2 and "--slab-max must be a number > 0 and <= 1000 m (got -1.0)" in r.output


def test_device_resolution_is_one_function(monkeypatch):
    import torch

    from cuboidcli.cli import common

    monkeypatch.setattr(torch.cuda, "is_available", lambda: False)
    assert resolve_device("auto") == "cpu" == api.resolve_device("cpu")
    with pytest.raises(ValueError, match=r"^device 'tpu': choose auto, cpu or cuda$"):
        resolve_device("tpu")
    with pytest.raises(ValueError, match="no CUDA device is available"):
        api.Fitter(device="cuda")
    import typer

    with pytest.raises(typer.Exit):
        common.resolve_device("cuda")
    assert common.resolve_device("auto") == "cpu"
    with pytest.raises(ValueError, match="^--device cuda: no CUDA device is available; use --device cpu or"):
        resolve_device("cuda", "--device")

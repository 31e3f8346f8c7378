"""Every ``cuboids train`` command runs its trainer in :func:`cuboidcli.cli.common.training_run`: a refused
run ends in one line with exit status 2 and leaves no empty OUT; Ctrl-C ends with status 130 and the
``--resume`` that continues the run. The trainers are replaced by stand-ins that fail at once."""

from __future__ import annotations

import pytest
from typer.testing import CliRunner

from cuboidcli.cli.main import app

#: command -> (the learn module and function it calls, whether it takes a DATA folder)
TRAINERS = {
    "solver": ("cuboidcli.learn.solver_train", "train_solver", False),
    "sampler": ("cuboidcli.learn.sampler_train", "train_sampler", True),
    "finetune": ("cuboidcli.learn.finetune", "finetune", True),
    "depth": ("cuboidcli.learn.depth_train", "train_depth", True),
    "seed": ("cuboidcli.learn.seed_train", "train_seed_sampler", True),
}
#: Commands without --device (the first-point sampler trains on the CPU).
CPU_ONLY = {"seed"}


def _run(command: str, tmp_path, monkeypatch, trainer, *more: str):
    import importlib

    module, name, takes_data = TRAINERS[command]
    monkeypatch.setattr(importlib.import_module(module), name, trainer)
    data = tmp_path / "data"
    data.mkdir(exist_ok=True)
    device = [] if command in CPU_ONLY else ["--device", "cpu"]
    args = ["train", command, *([str(data)] if takes_data else []), *device, *more]
    return CliRunner().invoke(app, args)


@pytest.mark.parametrize("command", sorted(TRAINERS))
def test_a_refused_run_fails_in_one_line_and_leaves_no_folder(command, tmp_path, monkeypatch):
    def refuse(*args, **kwargs):
        raise ValueError("batch 9 is larger than the 8 frames")

    out = tmp_path / "out"
    result = _run(command, tmp_path, monkeypatch, refuse, "--out", str(out))
    assert result.exit_code == 2, result.output
    assert "error: batch 9 is larger than the 8 frames" in result.output
    assert not out.exists()


@pytest.mark.parametrize("command", sorted(TRAINERS))
def test_ctrl_c_names_the_checkpoint_to_resume(command, tmp_path, monkeypatch):
    def interrupted(*args, **kwargs):
        out.mkdir(exist_ok=True)
        (out / "last.pt").write_bytes(b"state")
        raise KeyboardInterrupt

    out = tmp_path / "out"
    result = _run(command, tmp_path, monkeypatch, interrupted, "--out", str(out))
    assert result.exit_code == 130, result.output
    assert f"interrupted; continue with --resume {out / 'last.pt'}" in result.output


@pytest.mark.parametrize("command", sorted(TRAINERS))
def test_ctrl_c_before_the_first_checkpoint_has_nothing_to_resume(command, tmp_path, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    result = _run(command, tmp_path, monkeypatch, interrupted, "--out", str(tmp_path / "out"))
    assert result.exit_code == 130, result.output
    assert "nothing to resume" in result.output
    assert not (tmp_path / "out").exists()

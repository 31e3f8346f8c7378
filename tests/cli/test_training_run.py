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
    result = _run(command, tmp_path, monkeypatch, refuse, "--output", str(out))
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
    result = _run(command, tmp_path, monkeypatch, interrupted, "--output", str(out))
    assert result.exit_code == 130, result.output
    assert f"interrupted; continue with --resume {out / 'last.pt'}" in result.output


@pytest.mark.parametrize("command", sorted(TRAINERS))
def test_ctrl_c_before_the_first_checkpoint_has_nothing_to_resume(command, tmp_path, monkeypatch):
    def interrupted(*args, **kwargs):
        raise KeyboardInterrupt

    result = _run(command, tmp_path, monkeypatch, interrupted, "--output", str(tmp_path / "out"))
    assert result.exit_code == 130, result.output
    assert "nothing to resume" in result.output
    assert not (tmp_path / "out").exists()


def _calls(command: str, tmp_path, monkeypatch, *more: str):
    """The arguments the trainer got (callables left out: the commands pass fresh closures), and the
    command's output."""
    calls = []

    def record(*args, **kwargs):
        calls.append(
            ([a for a in args if not callable(a)], {k: v for k, v in kwargs.items() if not callable(v)})
        )
        return {"iteration": 0, "timed_out": False, "best": "best.pt"}  # the final record solver prints

    result = _run(command, tmp_path, monkeypatch, record, *more)
    assert result.exit_code == 0, result.output
    return calls, result.output


#: Old spellings that still work (hidden from --help, one warning): (old, new, value) per command.
RENAMED = [
    *((command, "--out", "--output", "run") for command in sorted(TRAINERS)),
    *((command, "--width", "--channels", "16") for command in ("sampler", "seed", "solver")),
]


@pytest.mark.parametrize(("command", "old", "new", "value"), RENAMED)
def test_an_old_spelling_works_as_the_new_one_with_a_warning(command, old, new, value, tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # the default output folder is relative
    if value == "run":
        value = str(tmp_path / "run")
    given_old, text_old = _calls(command, tmp_path, monkeypatch, old, value)
    given_new, text_new = _calls(command, tmp_path, monkeypatch, new, value)
    default, _ = _calls(command, tmp_path, monkeypatch)
    assert given_old == given_new and given_old != default
    assert text_old.count("deprecated") == 1 and f"{old} is deprecated; use {new}" in text_old
    assert "deprecated" not in text_new
    both = _run(command, tmp_path, monkeypatch, lambda *a, **k: None, old, value, new, value)
    assert both.exit_code == 2 and f"give only {new}" in both.output
    help_text = CliRunner().invoke(app, ["train", command, "--help"]).output
    assert new in help_text and f"{old} " not in help_text


def test_width_still_means_the_image_width_of_synth():
    """``--width`` of the train commands is spelled ``--channels``: only ``cuboids synth`` has a --width."""
    for command in TRAINERS:
        assert "--width " not in CliRunner().invoke(app, ["train", command, "--help"]).output

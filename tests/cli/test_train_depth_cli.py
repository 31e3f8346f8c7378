"""``cuboids train depth`` through its own Typer app: a real (tiny) training on frames of ``cuboids synth``,
resuming and extending it, Ctrl-C, and the one-line errors."""

from __future__ import annotations

import json
import subprocess
import sys

import numpy as np
import pytest
import torch
import typer
from typer.testing import CliRunner

from cuboidcli.cli.train_depth import register

# 8 train frames at batch 4: two steps per epoch, logged every step
TINY_RUN = ["--batch", "4", "--log-every", "1", "--threads", "1"]


@pytest.fixture(scope="module")
def app() -> typer.Typer:
    root, train = typer.Typer(), typer.Typer()
    register(train)
    root.add_typer(train, name="train")
    return root


def _run(app, *args):
    return CliRunner().invoke(app, ["train", "depth", *map(str, args)])


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    """Nine 64x48 synthetic rooms (splits by index % 10: 8 train, 1 val)."""
    from cuboidcli.camera import Camera
    from cuboidcli.synth.dataset import write_dataset

    base = Camera.preset("nyu")
    root = tmp_path_factory.mktemp("rgbd")
    write_dataset(root, 9, seed=1, camera=base.scaled(64 / base.width, 48 / base.height))
    return root


@pytest.fixture(autouse=True)
def keep_torch_threads():
    before = torch.get_num_threads()
    yield
    torch.set_num_threads(before)


def _records(out, event):
    lines = (out / "log.jsonl").read_text().splitlines()
    return [r for r in map(json.loads, lines) if r["event"] == event]


def test_trains_resumes_and_extends(app, dataset, tmp_path):
    from cuboidcli.depth.estimator import BuiltinDepthEstimator
    from cuboidcli.io.dataset import list_frames
    from cuboidcli.nets.depth import net_from_checkpoint

    out = tmp_path / "run"
    result = _run(app, dataset, "--epochs", 1, *TINY_RUN, "--output", out)
    assert result.exit_code == 0, result.output
    for name in ("best.pt", "last.pt", "log.jsonl", "config.json"):
        assert (out / name).is_file(), name
    best, named = (torch.load(out / name, weights_only=True) for name in ("best.pt", "depth_v2.pt"))
    assert best["state_dict"].keys() == named["state_dict"].keys()  # depth_v2.pt: a weights folder's name
    assert all(torch.equal(best["state_dict"][k], named["state_dict"][k]) for k in best["state_dict"])
    text = result.output
    assert "train / 1 val frames" in text and "epoch 1/1 step 2/2: loss" in text and "images/s" in text
    assert "val epoch 1/1: AbsRel" in text and "RMSE" in text and "delta<1.25" in text and "*best*" in text
    assert f"weights {out / 'best.pt'}" in text
    assert [r["epoch"] for r in _records(out, "val")] == [1]

    net = net_from_checkpoint(torch.load(out / "best.pt", weights_only=True))
    assert not net.training
    f = list_frames(dataset, "val")[0]
    depth = BuiltinDepthEstimator(net=net).predict(f.rgb(), f.camera)
    assert depth.shape == (48, 64) and np.isfinite(depth).all() and (depth > 0).all()

    # a finished run resumed without --epochs has nothing left to do
    again = _run(app, dataset, "--resume", out / "last.pt", "--output", out)
    assert again.exit_code == 0, again.output
    assert "done all 1 epochs" in again.output and len(_records(out, "val")) == 1

    # --epochs extends it; the schedule options the checkpoint fixes are reported as ignored
    more = _run(app, dataset, "--resume", out / "last.pt", "--epochs", 2, "--lr", 0.5, "--output", out)
    assert more.exit_code == 0, more.output
    assert "--lr: ignored with --resume" in more.output and "epoch 1 -> 2" in more.output
    assert [r["epoch"] for r in _records(out, "val")] == [1, 2]
    state = torch.load(out / "last.pt", weights_only=True)
    assert state["epoch"] == 2 and state["step"] == 4
    assert state["train_config"]["lr"] == pytest.approx(1e-3) and state["train_config"]["epochs"] == 2

    # a fresh run into a folder that holds one is refused rather than overwriting best.pt
    clash = _run(app, dataset, "--epochs", 1, "--output", out)
    assert clash.exit_code == 2 and "already holds a training run" in clash.output


def test_ctrl_c_points_at_last_pt(app, dataset, tmp_path, monkeypatch):
    import cuboidcli.learn.depth_train as train_module

    real = train_module.train_depth

    def interrupted_in_second_epoch(*args, on_event, **kwargs):
        def hook(record):
            on_event(record)
            if record["event"] == "train" and record["epoch"] == 1:
                raise KeyboardInterrupt

        return real(*args, on_event=hook, **kwargs)

    monkeypatch.setattr(train_module, "train_depth", interrupted_in_second_epoch)
    out = tmp_path / "cut"
    result = _run(app, dataset, "--epochs", 2, *TINY_RUN, "--output", out)
    assert result.exit_code == 130
    assert f"interrupted; continue with --resume {out / 'last.pt'}" in result.output
    monkeypatch.setattr(train_module, "train_depth", real)
    resumed = _run(app, dataset, "--resume", out / "last.pt", "--output", out)
    assert resumed.exit_code == 0, resumed.output
    assert torch.load(out / "last.pt", weights_only=True)["epoch"] == 2


@pytest.mark.parametrize(
    ("args", "message"),
    [
        (["--batch", "0"], "batch must be at least 1"),
        (["--min-crop", "1.5"], "min_crop must lie in (0, 1]"),
        (["--lr", "0"], "lr must be positive"),
        (["--max-minutes", "-1"], "max_minutes must be positive"),
        (["--device", "tpu"], "--device 'tpu': choose auto, cpu or cuda"),
        (["--batch", "9"], "batch 9 is larger than the 8 frames"),
        (["--white-balance", "1"], "white_balance must lie in [0, 1)"),
        (["--blur", "-1"], "blur must not be negative"),
        (["--grad-weight", "-0.1"], "grad_weight must not be negative"),
        (["--init", "nope.pt"], "--init nope.pt: no such weights file"),
    ],
)
def test_bad_values_fail_in_one_line(app, dataset, tmp_path, args, message):
    result = _run(app, dataset, *args, "--output", tmp_path / "o")
    assert result.exit_code == 2 and message in result.output, result.output
    assert "Traceback" not in result.output


def test_missing_inputs_fail_in_one_line(app, dataset, tmp_path):
    bad = _run(app, tmp_path / "missing", "--output", tmp_path / "o")
    assert bad.exit_code == 2 and "dataset folder not found" in bad.output
    bad = _run(app, dataset, "--resume", tmp_path / "nope.pt", "--output", tmp_path / "o")
    assert bad.exit_code == 2 and "no such checkpoint" in bad.output
    (tmp_path / "file").write_text("x")
    bad = _run(app, dataset, "--output", tmp_path / "file")
    assert bad.exit_code == 2 and "is a file" in bad.output
    bad = _run(app, dataset, "--resume", tmp_path / "file", "--output", tmp_path / "o")
    assert bad.exit_code == 2 and "cannot read" in bad.output
    weights = tmp_path / "weights.pt"
    torch.save({"config": {}, "state_dict": {}, "meta": {}}, weights)
    bad = _run(app, dataset, "--resume", weights, "--output", tmp_path / "o")
    assert bad.exit_code == 2 and "not a depth training checkpoint (use last.pt)" in bad.output


def test_json_prints_the_records_as_json_lines(app, dataset, tmp_path):
    r = _run(app, dataset, "--output", tmp_path / "m", "--epochs", "1", "--batch", "8", "--json")
    assert r.exit_code == 0, r.output
    records = [json.loads(line) for line in r.stdout.splitlines()]
    assert records[0]["event"] == "start" and records[-1]["event"] == "done" and records[-1]["epoch"] == 1
    assert (tmp_path / "m" / "best.pt").is_file()


def test_module_entry_point_of_the_depth_errors(dataset, tmp_path, capsys):
    """``python -m cuboidcli.cli.depth_evaluate``."""
    from cuboidcli.cli.depth_evaluate import main
    from cuboidcli.io.dataset import list_frames

    main([str(dataset), "--split", "val", "--output", str(tmp_path / "errors.json")])
    lines = capsys.readouterr().out.splitlines()
    val = [f.name for f in list_frames(dataset, "val")]
    assert [line.split()[0] for line in lines] == [*val, "mean"] and "AbsRel" in lines[-1]
    report = json.loads((tmp_path / "errors.json").read_text())
    assert set(report["frames"]) == set(val) and len(report["model"]["sha256"]) == 64
    with pytest.raises(SystemExit) as exit_info:
        main([str(tmp_path / "missing")])
    assert exit_info.value.code == 2
    usage = subprocess.run(
        [sys.executable, "-m", "cuboidcli.cli.depth_evaluate", "--help"], capture_output=True, text=True
    )
    assert usage.returncode == 0 and "python -m cuboidcli.cli.depth_evaluate" in usage.stdout


def test_init_starts_from_a_weights_file(app, dataset, tmp_path):
    """--init: the first run's best weights are the start of a second run, whose net (and canonical focal
    length) is theirs; at a learning rate too small to move them, the second run's weights are the first's."""
    first = tmp_path / "first"
    assert _run(app, dataset, "--output", first, "--epochs", "1", *TINY_RUN).exit_code == 0
    second = tmp_path / "second"
    r = _run(
        app,
        dataset,
        "--output",
        second,
        "--epochs",
        "1",
        "--init",
        first / "best.pt",
        "--lr",
        "1e-12",
        "--grad-weight",
        "0.5",
        "--blur",
        "1",
        "--noise",
        "0.02",
        "--white-balance",
        "0.1",
        *TINY_RUN,
    )
    assert r.exit_code == 0, r.output
    a = torch.load(first / "best.pt", weights_only=True)
    b = torch.load(second / "best.pt", weights_only=True)
    assert a["config"] == b["config"]
    for name, value in a["state_dict"].items():
        if value.is_floating_point() and "running" not in name:
            assert torch.allclose(value, b["state_dict"][name], atol=1e-6), name
    fresh = _run(app, dataset, "--output", tmp_path / "fresh", "--epochs", "1", "--lr", "1e-12", *TINY_RUN)
    assert fresh.exit_code == 0
    c = torch.load(tmp_path / "fresh" / "best.pt", weights_only=True)["state_dict"]
    assert not torch.allclose(a["state_dict"]["head.weight"], c["head.weight"])
    (tmp_path / "junk.pt").write_bytes(b"not a checkpoint")
    bad = _run(app, dataset, "--output", tmp_path / "o", "--init", tmp_path / "junk.pt", *TINY_RUN)
    assert bad.exit_code == 2 and "cannot read --init" in bad.output


def test_depth_errors_take_the_old_out_with_one_warning(dataset, tmp_path, capsys):
    """``--output`` (``-o``) names the report file, as on the other commands; ``--out`` still works, hidden,
    with one warning, and writes the same report."""
    from cuboidcli.cli.depth_evaluate import main

    main([str(dataset), "--split", "val", "-o", str(tmp_path / "new.json")])
    new = capsys.readouterr()
    main([str(dataset), "--split", "val", "--out", str(tmp_path / "old.json")])
    old = capsys.readouterr()
    assert old.out == new.out and "deprecated" not in new.err
    assert old.err.count("deprecated") == 1 and "--out is deprecated; use --output" in old.err
    assert json.loads((tmp_path / "old.json").read_text()) == json.loads((tmp_path / "new.json").read_text())
    with pytest.raises(SystemExit) as exit_info:
        main([str(dataset), "--out", str(tmp_path / "a.json"), "--output", str(tmp_path / "b.json")])
    assert exit_info.value.code == 2 and "give only --output" in capsys.readouterr().err

"""A corpus of hostile inputs run through every command: one line on stderr, exit 2, no traceback, nothing
written. And an unexpected internal error: one line naming the file that holds the traceback, exit 1."""

from __future__ import annotations

import json
import zipfile
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from typer.testing import CliRunner

from cuboidcli.cli.main import app
from cuboidcli.io.checkpoints import CheckpointError, load_net, read_checkpoint
from cuboidcli.nets.checkpoint import checkpoint_dict
from cuboidcli.nets.solver import SolverNet, SolverNetConfig, net_from_checkpoint
from tests.conftest import write_room_dataset

SAMPLE = Path(__file__).resolve().parents[1] / "cuboidcli" / "data" / "sample"


class Payload:
    """What an attacker or a wrong download puts in a pickle: an object that is not a tensor."""


def _good_result() -> dict:
    return {
        "schema": "cuboids/1",
        "camera": {"fx": 500.0, "fy": 500.0, "cx": 319.5, "cy": 239.5, "width": 640, "height": 480},
        "cuboids": [
            {"center": [0.0, 0.0, 3.0], "half_size": [0.5, 0.5, 0.5], "rotation": np.eye(3).tolist()}
        ],
    }


def _broken_result(edit) -> dict:
    d = _good_result()
    edit(d)
    return d


@pytest.fixture(scope="module")
def corpus(tmp_path_factory, nyu_camera) -> Path:
    """Every hostile file once, in one folder."""
    root = tmp_path_factory.mktemp("hostile")
    net = SolverNet(SolverNetConfig(width=16, layers=1, heads=2, ff=16))
    good = checkpoint_dict(net)
    torch.save(good, root / "tiny_solver.pt")
    torch.save({**good, "extra": Payload()}, root / "object.pt")
    for name, kind_key in (("sampler_v2.pt", "maps"), ("solver_v2.pt", "heads")):
        (root / "object_dir").mkdir(exist_ok=True)
        torch.save({"config": {kind_key: 1}, "state_dict": {}, "x": Payload()}, root / "object_dir" / name)
    data = (root / "tiny_solver.pt").read_bytes()
    (root / "truncated.pt").write_bytes(data[: len(data) // 2])
    (root / "empty.pt").write_bytes(b"")
    (root / "notes.pt").write_text("these are not weights\n")
    with zipfile.ZipFile(root / "other_tool.pt", "w") as z:
        z.writestr("model/data.json", "{}")
    torch.save([1, 2, 3], root / "list.pt")
    torch.save({"weights": torch.zeros(3)}, root / "foreign_dict.pt")
    missing = {k: v for k, v in good["state_dict"].items() if not k.endswith("bias")}
    torch.save({**good, "state_dict": missing}, root / "missing_keys.pt")
    reshaped = dict(good["state_dict"])
    key = next(iter(reshaped))
    reshaped[key] = torch.zeros(*reshaped[key].shape, 2)
    torch.save({**good, "state_dict": reshaped}, root / "wrong_shape.pt")
    torch.save({"config": {"maps": 4}, "state_dict": {}}, root / "sampler_kind.pt")
    torch.save({"config": {"channels": [8]}, "state_dict": {}}, root / "depth_kind.pt")
    np.save(root / "complex.npy", np.ones((48, 64), np.complex64))
    np.savez(root / "two.npz", a=np.ones((48, 64)), b=np.ones((48, 64)))
    png = (SAMPLE / "sample_depth.png").read_bytes()
    (root / "truncated_depth.png").write_bytes(png[: len(png) // 3])
    (root / "text_depth.png").write_text("not a png")
    for name, doc in {
        "no_camera.json": _broken_result(lambda d: d.pop("camera")),
        "no_fx.json": _broken_result(lambda d: d["camera"].pop("fx")),
        "no_cuboids.json": _broken_result(lambda d: d.pop("cuboids")),
        "short_half_size.json": _broken_result(lambda d: d["cuboids"][0].update(half_size=[1, 2])),
        "not_rotation.json": _broken_result(lambda d: d["cuboids"][0].update(rotation=[[2, 0, 0]] * 3)),
        "string_center.json": _broken_result(lambda d: d["cuboids"][0].update(center="0,0,3")),
        "list.json": [1, 2],
    }.items():
        (root / name).write_text(json.dumps(doc))
    (root / "not_json.json").write_text("{'schema': ")
    (root / "binary.json").write_bytes(b'{"fx": 5\n\xd0\xcf\x11\xe0' + bytes(range(256)))
    room = np.random.default_rng(0).uniform(0.0, 3.0, (5000, 3))
    for name, points in {
        "nan_room.npy": np.where(np.arange(5000)[:, None] == 10, np.nan, room),
        "inf_room.npy": np.where(np.arange(5000)[:, None] == 10, np.inf, room),
        "huge_room.npy": room * 1e6,
        "tiny_room.npy": room * 1e-6,
        "no_points.npy": room[:0],
    }.items():
        np.save(root / name, points)
    (root / "no_vertices.ply").write_text(
        "ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nproperty float y\nproperty float z\n"
        "end_header\n"
    )
    write_room_dataset(root / "dataset", nyu_camera.scaled(0.25))
    for name, splits in (("bad_splits", b"\x89PNG\r\n"), ("list_splits", b'["a", "b"]')):
        write_room_dataset(root / name, nyu_camera.scaled(0.25))
        (root / name / "splits.json").write_bytes(splits)
    return root


FIT = ["fit", "--depth", "{sample}/sample_depth.png", "-K", "{sample}/camera.json", "--hypotheses", "64"]
EXPORT = ["export", "{c}/{file}", "--glb", "{out}/x.glb"]

CASES = {
    # weights files: refused objects, through a folder and as a single file, for each network
    "learned sampler, folder with an object": (
        [*FIT, "--sampler", "learned", "--weights", "{c}/object_dir"],
        "holds a Python object",
    ),
    "neural solver, folder with an object": (
        [*FIT, "--solver", "neural", "--weights", "{c}/object_dir"],
        "holds a Python object",
    ),
    "neural solver, file with an object": (
        [*FIT, "--solver", "neural", "--weights", "{c}/object.pt"],
        "Payload",
    ),
    "learned sampler, file with an object": (
        [*FIT, "--sampler", "learned", "--weights", "{c}/object.pt"],
        "refused",
    ),
    "truncated weights": ([*FIT, "--solver", "neural", "--weights", "{c}/truncated.pt"], "truncated"),
    "empty weights": ([*FIT, "--solver", "neural", "--weights", "{c}/empty.pt"], "empty file"),
    "text file named .pt": ([*FIT, "--solver", "neural", "--weights", "{c}/notes.pt"], "cannot read"),
    "zip of another tool": ([*FIT, "--solver", "neural", "--weights", "{c}/other_tool.pt"], "cannot read"),
    "a pickled list": ([*FIT, "--solver", "neural", "--weights", "{c}/list.pt"], "holds a list"),
    "a torch dict of another tool": (
        [*FIT, "--solver", "neural", "--weights", "{c}/foreign_dict.pt"],
        "not a network of this tool",
    ),
    "missing parameters": ([*FIT, "--solver", "neural", "--weights", "{c}/missing_keys.pt"], "do not fit"),
    "reshaped parameters": ([*FIT, "--solver", "neural", "--weights", "{c}/wrong_shape.pt"], "do not fit"),
    "sampler file for the solver": (
        [*FIT, "--solver", "neural", "--weights", "{c}/sampler_kind.pt"],
        "holds the sampler network",
    ),
    "depth file for the sampler": (
        [*FIT, "--sampler", "learned", "--weights", "{c}/depth_kind.pt"],
        "holds the depth network",
    ),
    "weights nothing loads": ([*FIT, "--weights", "{c}/tiny_solver.pt"], "loads no network"),
    "depth model with an object": (
        ["fit", "{sample}/sample.png", "-K", "{sample}/camera.json", "--depth-model", "{c}/object.pt"],
        "refused",
    ),
    # depth maps
    "truncated depth PNG": (
        ["fit", "--depth", "{c}/truncated_depth.png", "-K", "{sample}/camera.json"],
        "cannot decode",
    ),
    "text file named .png": (["fit", "--depth", "{c}/text_depth.png"], "cannot decode"),
    # point clouds
    "cloud with a NaN point": (["fit", "{c}/nan_room.npy"], "1 of 5000 points have NaN or inf coordinates"),
    "cloud with an inf point": (["fit", "{c}/inf_room.npy"], "1 of 5000 points have NaN or inf coordinates"),
    "cloud a thousand km across": (["fit", "{c}/huge_room.npy"], "too large for a room; check --unit"),
    "cloud a few microns across": (["fit", "{c}/tiny_room.npy"], "too small for a room; check --unit"),
    "PLY without vertices": (["fit", "{c}/no_vertices.ply"], "has 0 points"),
    "array of no points": (["fit", "{c}/no_points.npy"], "holds no points ((N, 3) or (N, 6)"),
    # depth arrays
    "complex depth": (["fit", "--depth", "{c}/complex.npy", "--camera", "nyu"], "holds complex numbers"),
    "npz of two unnamed arrays": (
        ["fit", "--depth", "{c}/two.npz", "--camera", "nyu"],
        "holds several arrays (a, b) and none is named depth",
    ),
    # results for export
    "result without camera": (EXPORT, "field 'camera' is missing", "no_camera.json"),
    "result without fx": (EXPORT, "field 'camera.fx' is missing", "no_fx.json"),
    "result without cuboids": (EXPORT, "field 'cuboids' is missing", "no_cuboids.json"),
    "half_size of two numbers": (
        EXPORT,
        "'cuboids[0].half_size' must be 3 finite numbers",
        "short_half_size.json",
    ),
    "rotation that is none": (EXPORT, "'cuboids[0].rotation' is not a rotation", "not_rotation.json"),
    "centre as a string": (EXPORT, "'cuboids[0].center' must be 3", "string_center.json"),
    "result is a list": (EXPORT, "holds a JSON list", "list.json"),
    "result is not JSON": (EXPORT, "not valid JSON", "not_json.json"),
    "result is a binary file": (EXPORT, "not UTF-8 text", "binary.json"),
    "intrinsics in a binary file": (
        ["fit", "--depth", "{sample}/sample_depth.png", "-K", "{c}/binary.json"],
        "binary.json is not valid JSON (not UTF-8 text (byte 0xd0) at line 2)",
    ),
    "evaluate, splits.json not JSON": (
        ["evaluate", "{c}/bad_splits", "--split", "test", "-o", "{out}/eval"],
        "splits.json is not valid JSON (not UTF-8 text",
    ),
    "evaluate, splits.json a list": (
        ["evaluate", "{c}/list_splits", "--split", "test", "-o", "{out}/eval"],
        "splits.json must map split names to lists of frame names",
    ),
    "train sampler, splits.json not JSON": (
        ["train", "sampler", "{c}/bad_splits", "--output", "{out}/run"],
        "splits.json is not valid JSON",
    ),
    # evaluate and the trainers
    "evaluate with an object in the weights": (
        ["evaluate", "{c}/dataset", "--sampler", "learned", "--weights", "{c}/object.pt", "-o", "{out}/eval"],
        "refused",
    ),
    "evaluate, weights nothing loads": (
        ["evaluate", "{c}/dataset", "--weights", "{c}/tiny_solver.pt", "-o", "{out}/eval"],
        "loads no network",
    ),
    "train solver, resume from an object": (
        ["train", "solver", "--resume", "{c}/object.pt", "--output", "{out}/run"],
        "refused",
    ),
    "train sampler, resume from a zip": (
        ["train", "sampler", "{c}/dataset", "--resume", "{c}/other_tool.pt", "--output", "{out}/run"],
        "cannot read",
    ),
    "train depth, resume truncated": (
        ["train", "depth", "{c}/dataset", "--resume", "{c}/truncated.pt", "--output", "{out}/run"],
        "truncated",
    ),
    "train finetune, sampler with an object": (
        ["train", "finetune", "{c}/dataset", "--sampler-weights", "{c}/object.pt", "--output", "{out}/run"],
        "refused",
    ),
    "synth, no frames": (["synth", "{out}/synth", "-n", "0"], "--count must be a whole number from 1"),
}


def _invoke(args: list[str], corpus: Path, out: Path, file: str = ""):
    values = {"c": corpus, "sample": SAMPLE, "out": out, "file": file}
    args = [a.format(**values) for a in args]
    return CliRunner().invoke(app, args)


@pytest.mark.parametrize("case", list(CASES))
def test_hostile_input_gets_one_line(case, corpus, tmp_path, monkeypatch):
    args, needle, *file = CASES[case]
    out = tmp_path / "out"
    out.mkdir()
    monkeypatch.chdir(out)  # fit's default output goes here too
    result = _invoke(args, corpus, out, *file)
    stderr_lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert result.exit_code == 2, (case, result.output, result.exception)
    assert len(stderr_lines) == 1 and stderr_lines[0].startswith("error: "), result.stderr
    assert needle in stderr_lines[0], stderr_lines[0]
    assert "Traceback" not in result.output and "WARN" not in result.output
    assert result.stdout == ""
    assert not any(out.iterdir()), sorted(out.rglob("*"))  # nothing written, not even an empty folder


def test_every_command_is_in_the_corpus():
    covered = {CASES[c][0][0] for c in CASES} | {" ".join(CASES[c][0][:2]) for c in CASES}
    for command in (
        "fit",
        "export",
        "evaluate",
        "synth",
        "train solver",
        "train sampler",
        "train depth",
        "train finetune",
    ):
        assert command in covered


def test_internal_error_prints_one_line_and_saves_the_traceback(corpus, tmp_path, monkeypatch):
    import cuboidcli.fitting.pipeline as pipeline

    def broken(*args, **kwargs):
        raise RuntimeError("the solver lost its way\nsecond line")

    monkeypatch.setattr(pipeline, "estimate", broken)
    monkeypatch.setattr("tempfile.tempdir", str(tmp_path))
    monkeypatch.chdir(tmp_path)
    result = _invoke([*FIT, "-o", "{out}/r.json"], corpus, tmp_path)
    lines = [line for line in result.stderr.splitlines() if line.strip()]
    assert result.exit_code == 1 and len(lines) == 1, result.stderr
    assert "internal error (RuntimeError: the solver lost its way second line)" in lines[0]
    assert "Traceback" not in result.output and not (tmp_path / "r.json").exists()
    saved = list(tmp_path.glob("cuboids-crash-*.txt"))
    assert len(saved) == 1 and str(saved[0]) in lines[0]
    text = saved[0].read_text()
    assert "Traceback (most recent call last)" in text and "def broken" not in text
    assert "RuntimeError: the solver lost its way" in text and "command: cuboids" in text
    # --debug shows the exception itself
    debug = _invoke(["--debug", *FIT, "-o", "{out}/r.json"], corpus, tmp_path)
    assert isinstance(debug.exception, RuntimeError)


def test_library_warnings_stay_out_of_the_output(corpus, tmp_path, monkeypatch):
    """A torch warning during a fit is not printed; the tool's own input warnings still are."""
    import warnings

    import cuboidcli.fitting.pipeline as pipeline

    real = pipeline.fit_depth

    def noisy(*args, **kwargs):
        warnings.warn_explicit("a library talks", UserWarning, "torch/nn/modules/module.py", 1, "torch.nn")
        return real(*args, **kwargs)

    monkeypatch.setattr(pipeline, "fit_depth", noisy)
    monkeypatch.chdir(tmp_path)
    sparse = np.zeros((480, 640), np.uint16)
    sparse[200:230, 300:330] = 2000  # 0.3 % valid pixels: an input warning of ours
    cv2.imwrite(str(tmp_path / "sparse.png"), sparse)
    result = CliRunner().invoke(
        app, ["fit", "--depth", str(tmp_path / "sparse.png"), "--hypotheses", "64", "-q", "-o", "r.json"]
    )
    assert result.exit_code == 0, result.output
    assert "a library talks" not in result.output
    assert "depth pixels are valid" in result.stderr


def test_checkpoint_errors_in_the_library(corpus):
    """The one reader raises CheckpointError (an InputError) for each bad file; a good file loads."""
    net = load_net(corpus / "tiny_solver.pt", "solver", net_from_checkpoint)
    assert isinstance(net, SolverNet) and not net.training
    for name in ("object.pt", "truncated.pt", "empty.pt", "notes.pt", "other_tool.pt", "list.pt"):
        with pytest.raises(CheckpointError):
            read_checkpoint(corpus / name)
    for name in ("foreign_dict.pt", "missing_keys.pt", "wrong_shape.pt", "sampler_kind.pt"):
        with pytest.raises(CheckpointError, match=str(corpus / name)):
            load_net(corpus / name, "solver", net_from_checkpoint)
    with pytest.raises(CheckpointError, match="not found"):
        read_checkpoint(corpus / "absent.pt")


@pytest.mark.parametrize("args", [["no-such-command"], ["fit", "--no-such-option"], ["train", "nothing"]])
def test_usage_errors_are_not_internal_errors(args):
    result = CliRunner().invoke(app, args)
    assert result.exit_code == 2 and "internal error" not in result.output

"""`cuboids fit DIR` on every engine (this process, local processes, a local Ray): the same cuboids, resumable
runs, failed frames reported while the others go on. Frames are 80x60 renders, fits are small."""

from __future__ import annotations

import json
import math
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from cuboidcli.camera import Camera
from cuboidcli.cli.main import app
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.raycast import render_depth
from cuboidcli.scaleout import Outcome, Summary, run_tasks

CAM = Camera.preset("nyu").scaled(0.125)  # 80x60
K = f"{CAM.fx},{CAM.fy},{CAM.cx},{CAM.cy}"
SMALL = ["--hypotheses", "48", "--max-cuboids", "3", "--grid-step", "2", "--device", "cpu", "-q"]


def scene(i: int) -> list[Cuboid]:
    room = Cuboid([0.0, -0.2, 2.5], [2.5, 1.5, 3.0], np.eye(3))
    a = math.radians(20.0 * i)
    rot = np.array([[math.cos(a), 0.0, math.sin(a)], [0.0, 1.0, 0.0], [-math.sin(a), 0.0, math.cos(a)]])
    return [room, Cuboid([-0.6 + 0.4 * i, 0.9, 3.0 + 0.2 * i], [0.5, 0.4, 0.4], rot)]


@pytest.fixture(scope="module")
def frames(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("frames")
    for i in range(4):
        cv2.imwrite(str(root / f"f{i}.png"), np.round(render_depth(CAM, scene(i)) * 1000).astype(np.uint16))
    return root


def fit_dir(folder: Path, out: Path, *extra) -> object:
    return CliRunner().invoke(app, ["fit", "--depth", str(folder), "-K", K, "-o", str(out), *SMALL, *extra])


def cuboids_of(out: Path) -> dict[str, list]:
    return {p.name: json.loads(p.read_text())["cuboids"] for p in sorted(out.glob("*_cuboids.json"))}


@pytest.fixture(scope="module")
def one_process(frames, tmp_path_factory) -> dict[str, list]:
    out = tmp_path_factory.mktemp("one") / "res"
    r = fit_dir(frames, out)
    assert r.exit_code == 0, r.output
    return cuboids_of(out)


def test_workers_fit_the_same_cuboids_as_one_process(frames, one_process, tmp_path):
    assert len(one_process) == 4 and all(len(c) >= 1 for c in one_process.values())
    r = fit_dir(frames, tmp_path / "two", "--workers", "2")
    assert r.exit_code == 0, r.output
    assert cuboids_of(tmp_path / "two") == one_process


def test_local_ray_fits_the_same_cuboids(frames, one_process, tmp_path):
    pytest.importorskip("ray")
    r = fit_dir(frames, tmp_path / "ray", "--ray", "--workers", "2")
    assert r.exit_code == 0, r.output
    assert cuboids_of(tmp_path / "ray") == one_process


def test_rerun_skips_complete_frames_and_redoes_the_rest(frames, tmp_path):
    out = tmp_path / "res"
    assert fit_dir(frames, out, "--glb").exit_code == 0
    stamps = {p.name: p.stat().st_mtime_ns for p in out.iterdir()}
    (out / "f1_cuboids.json").write_text("{not json")  # an interrupted or damaged frame
    (out / "f2_cuboids.glb").unlink()  # a frame whose outputs are incomplete
    r = CliRunner().invoke(
        app, ["fit", "--depth", str(frames), "-K", K, "-o", str(out), *SMALL[:-1], "--glb"]
    )
    assert r.exit_code == 0, r.output
    assert "2 done, 2 skipped, 0 failed" in r.output
    assert json.loads((out / "f1_cuboids.json").read_text())["schema"] == "cuboids/1"
    assert (out / "f2_cuboids.glb").is_file()
    for name in ("f0_cuboids.json", "f3_cuboids.json", "f0_cuboids.glb"):
        assert (out / name).stat().st_mtime_ns == stamps[name]  # skipped: not written again
    # Other settings are not the same output: every frame is fitted again, as with --no-skip-existing.
    r = CliRunner().invoke(
        app, ["fit", "--depth", str(frames), "-K", K, "-o", str(out), *SMALL[:-1], "--glb", "--seed", "1"]
    )
    assert "4 done, 0 skipped" in r.output
    r = CliRunner().invoke(
        app,
        ["fit", "--depth", str(frames), "-K", K, "-o", str(out), *SMALL[:-1], "--glb", "--seed", "1"]
        + ["--no-skip-existing"],
    )
    assert "4 done, 0 skipped" in r.output


def test_a_failed_frame_is_reported_and_the_others_go_on(frames, tmp_path):
    folder = tmp_path / "mixed"
    folder.mkdir()
    for name in ("f0.png", "f1.png"):
        (folder / name).write_bytes((frames / name).read_bytes())
    cv2.imwrite(str(folder / "bad.png"), np.zeros((60, 80), np.uint8))  # 8-bit: not a depth map
    (folder / "broken.png").write_bytes(b"not a png")
    r = CliRunner().invoke(
        app, ["fit", "--depth", str(folder), "-K", K, "-o", str(tmp_path / "out"), *SMALL[:-1]]
    )
    assert r.exit_code == 1
    assert "failed bad.png:" in r.output and "8-bit" in r.output
    assert "failed broken.png:" in r.output
    assert "2 done, 0 skipped, 2 failed" in r.output
    assert sorted(p.name for p in (tmp_path / "out").iterdir()) == ["f0_cuboids.json", "f1_cuboids.json"]


def test_scale_out_options_need_a_folder_and_valid_values(frames, tmp_path):
    depth = str(frames / "f0.png")
    r = CliRunner().invoke(app, ["fit", "--depth", depth, "-K", K, "--workers", "2"])
    assert r.exit_code == 2 and "fit the inputs of a folder" in r.output
    r = CliRunner().invoke(app, ["fit", "--depth", str(frames), "-K", K, "--workers", "0"])
    assert r.exit_code == 2 and "--workers must be a whole number from 1 to 1024 (got 0)" in r.output
    r = CliRunner().invoke(app, ["fit", "--depth", str(frames), "-K", K, "--ray-address", " "])
    assert r.exit_code == 2 and "--ray-address must be auto, HOST:PORT or ray://" in r.output


def _square(x: int) -> Outcome:
    if x == 3:
        raise RuntimeError("three is unlucky")
    return Outcome(f"n{x}", "done", value=x * x)


def test_engine_keeps_task_order_and_turns_crashes_into_failed_frames():
    seen = []
    outcomes = run_tasks(
        _square, [(i,) for i in range(5)], [f"n{i}" for i in range(5)], on_result=lambda i, o: seen.append(i)
    )
    assert seen == [0, 1, 2, 3, 4]
    assert [o.value for o in outcomes] == [0, 1, 4, None, 16]
    assert outcomes[3].status == "failed" and outcomes[3].message == "RuntimeError: three is unlucky"
    summary = Summary()
    for o in outcomes:
        summary.add(o)
    assert summary.line() == "4 done, 0 skipped, 1 failed"
    with pytest.raises(ValueError, match="workers must be at least 1"):
        run_tasks(_square, [], [], workers=0)

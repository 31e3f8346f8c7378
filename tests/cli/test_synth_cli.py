"""``cuboids synth`` through its own Typer app (independent of the other subcommands)."""

import json

import cv2
import numpy as np
import pytest
import typer
from typer.testing import CliRunner

from cuboidcli.cli import synth as synth_cli
from cuboidcli.io.sequence import read_sequence
from cuboidcli.load.room import is_room_input
from cuboidcli.synth.scan import read_scan_truth


@pytest.fixture(scope="module")
def app() -> typer.Typer:
    app = typer.Typer()
    synth_cli.register(app)

    @app.callback()
    def root() -> None:  # keeps "synth" a subcommand, as in the real app
        pass

    return app


def _run(app, *args):
    return CliRunner().invoke(app, ["synth", *map(str, args)])


def _tree(root):
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_synth_writes_a_dataset(app, tmp_path):
    out = tmp_path / "ds"
    result = _run(app, out, "--count", 2, "--seed", 1, "--width", 96)
    assert result.exit_code == 0, result.output
    assert "wrote 2 frames (96x72)" in result.output
    for folder in ("depth", "rgb", "instances"):
        assert sorted(p.name for p in (out / folder).iterdir()) == ["000000.png", "000001.png"]
    cams = json.loads((out / "cameras.json").read_text())
    assert (
        set(cams) == {"000000", "000001"} and cams["000000"]["width"] == 96 and cams["000000"]["height"] == 72
    )
    assert cams["000000"]["fx"] == pytest.approx(518.8579 * 96 / 640)
    gt = json.loads((out / "cuboids" / "000001.json").read_text())
    assert gt["schema"] == "cuboids/1" and gt["settings"]["seed"] == [1, 1]
    assert json.loads((out / "synth.json").read_text())["seed"] == 1


def test_synth_is_byte_identical_across_runs_and_workers(app, tmp_path):
    a, b = tmp_path / "a", tmp_path / "b"
    assert _run(app, a, "-n", 2, "--seed", 4, "--width", 64).exit_code == 0
    assert _run(app, b, "-n", 2, "--seed", 4, "--width", 64, "--workers", 2).exit_code == 0
    assert _tree(a) == _tree(b)


def test_synth_depth_flags(app, tmp_path):
    dense = tmp_path / "dense"
    assert _run(app, dense, "-n", 1, "--width", 80, "--inpaint").exit_code == 0
    depth = cv2.imread(str(dense / "depth" / "000000.png"), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16 and (depth > 0).all()
    clean = tmp_path / "clean"
    assert _run(app, clean, "-n", 1, "--width", 80, "--clean").exit_code == 0
    exact = cv2.imread(str(clean / "depth" / "000000.png"), cv2.IMREAD_UNCHANGED)
    assert (exact > 0).mean() > 0.95  # no holes inside the sensor's range


@pytest.mark.parametrize(
    "args, message",
    [
        (["--count", "0"], "--count 0"),
        (["--camera", "kinect9"], "--camera 'kinect9'"),
        (["--width", "8"], "too small"),
        (["--workers", "0"], "--workers 0"),
        (["--views", "0"], "--views 0"),
    ],
)
def test_synth_reports_bad_options_in_one_line(app, tmp_path, args, message):
    result = _run(app, tmp_path / "ds", *args)
    assert result.exit_code == 2
    assert message in result.output and "Traceback" not in result.output
    assert not (tmp_path / "ds").exists()


def test_synth_refuses_a_file_as_output(app, tmp_path):
    target = tmp_path / "file.txt"
    target.write_text("x")
    result = _run(app, target, "-n", 1)
    assert result.exit_code == 2 and "is a file" in result.output


def test_synth_views_writes_room_scans(app, tmp_path):
    out = tmp_path / "rooms"
    result = _run(app, out, "-n", 2, "--views", 3, "--seed", 7, "--width", 160)
    assert result.exit_code == 0, result.output
    assert "wrote 2 room scans (3 views each, 160x120)" in result.output
    assert sorted(p.name for p in out.iterdir()) == ["scene_0000", "scene_0001"]  # no frame dataset beside
    for i, scene in enumerate(sorted(out.iterdir())):
        names = [f"{k:06d}" for k in range(3)]
        for folder, suffix in (("depth", ".png"), ("color", ".png"), ("instances", ".png"), ("pose", ".txt")):
            assert sorted(p.name for p in (scene / folder).iterdir()) == [n + suffix for n in names]
        depth = cv2.imread(str(scene / "depth" / "000002.png"), cv2.IMREAD_UNCHANGED)
        assert depth.shape == (120, 160) and depth.dtype == np.uint16 and (depth > 0).mean() > 0.5
        pose = np.loadtxt(scene / "pose" / "000001.txt")
        assert pose.shape == (4, 4) and pose[3] == pytest.approx([0, 0, 0, 1])
        assert json.loads((scene / "cameras.json").read_text())["width"] == 160
        gt_doc = json.loads((scene / "gt.json").read_text())
        assert gt_doc["frame"] == "world" and gt_doc["settings"]["seed"] == [7, i]
        assert gt_doc["settings"]["views"] == 3
        gt, points, instance = read_scan_truth(scene)
        kinds = {c.kind for c in gt}
        assert {"floor", "wall", "object"} <= kinds and len(points) == len(instance) > 1000
        assert set(np.unique(instance)) <= {c.extras["object"] for c in gt}
        # a posed sequence that cuboids fit reads as a room
        assert is_room_input(scene) and len(read_sequence(scene).frames) == 3
    # the two rooms differ
    assert (out / "scene_0000" / "gt.json").read_bytes() != (out / "scene_0001" / "gt.json").read_bytes()


def test_preset_is_the_old_spelling_of_camera(app, tmp_path):
    """``--camera`` names the intrinsics preset (as on ``cuboids fit``); ``--preset`` still works, hidden,
    with one warning, and writes the same files."""
    old = _run(app, tmp_path / "old", "-n", 1, "--width", 64, "--preset", "tum")
    new = _run(app, tmp_path / "new", "-n", 1, "--width", 64, "--camera", "tum")
    assert old.exit_code == 0 and new.exit_code == 0, old.output + new.output
    assert old.output.count("deprecated") == 1 and "--preset is deprecated; use --camera" in old.output
    assert "deprecated" not in new.output
    assert _tree(tmp_path / "old") == _tree(tmp_path / "new")
    cams = json.loads((tmp_path / "new" / "cameras.json").read_text())
    assert cams["000000"]["fx"] == pytest.approx(525.0 * 64 / 640)  # TUM's, not NYU's 518.86
    both = _run(app, tmp_path / "both", "-n", 1, "--width", 64, "--preset", "tum", "--camera", "scannet")
    assert both.exit_code == 2 and "give only --camera" in both.output
    refused = _run(app, tmp_path / "refused", "-n", 0, "--preset", "tum")  # the refusal alone
    assert refused.exit_code == 2
    assert refused.output.strip().splitlines() == ["error: --count 0: give at least 1 frame"]
    help_text = _run(app, "--help").output
    assert "--camera" in help_text and "--preset" not in help_text

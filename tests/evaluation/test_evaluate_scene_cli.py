"""``cuboids evaluate DIR`` on room scans (cuboidcli/cli/evaluate_scene.py, cuboidcli/evaluation/scene_run.py)
end to end on two tiny scans (160x120, 3 views) through the command's own Typer app."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cuboidcli import __version__
from cuboidcli.camera import Camera
from cuboidcli.evaluation import scene_run
from cuboidcli.fitting.config import FitConfig
from cuboidcli.load import load
from cuboidcli.synth.scan import generate_room_scan, write_room_scan
from tests.evaluation.conftest import one_line_error, run_evaluate

#: A quick estimator: the test is about the command, not the numbers (still well above chance).
QUICK = ["--max-cuboids", "8", "--hypotheses", "64", "--fast", "--device", "cpu"]
#: The per-room keys the table is made of, each in every row of scenes.json.
KEYS = (
    "n_cuboids",
    "auc20cm_pct",
    "auc5cm_pct",
    "object_recall_pct",
    "object_precision_pct",
    "object_box_recall_iou0.25_pct",
    "object_box_recall_iou0.5_pct",
    "shell_box_recall_iou0.25_pct",
    "seconds",
)


@pytest.fixture(scope="module")
def rooms(tmp_path_factory):
    """Two room scans as cuboids synth --views 3 --width 160 writes them, and a folder that is no scan."""
    root = tmp_path_factory.mktemp("rooms")
    camera = Camera.preset("nyu").scaled(0.25, 0.25)
    for i in range(2):
        write_room_scan(root / f"scene_{i:04d}", generate_room_scan([5, i], 3, camera))
    (root / "notes").mkdir()
    return root


def test_room_scans_with_the_baseline(app, rooms, tmp_path):
    out = tmp_path / "out"
    result = run_evaluate(app, rooms, "--baseline", "-o", out, *QUICK)
    assert result.exit_code == 0, result.output
    for text in ("2 room scans", "cuboids (views)", "open3d planes+clusters", "AUC@20 cm %", "wrote"):
        assert text in result.output
    doc = json.loads((out / "scenes.json").read_text())
    assert doc["schema"] == "cuboids-scenes/1" and doc["version"] == __version__
    assert doc["command"].startswith("cuboids ") and doc["data"] == str(rooms.resolve())
    settings = doc["settings"]
    assert settings["bare"] is False and settings["baseline"] is True
    assert settings["fit"]["visibility"] == "auto" and settings["fit"]["max_cuboids"] == 8
    assert "scene" not in settings  # the room settings are the fit's
    assert settings["fit"]["hypotheses"] == 64 and settings["fit"]["sampler"] == "sequential"
    assert doc["methods"] == {"cuboids": "cuboids (views)", "baseline": "open3d planes+clusters"}
    rows = doc["scenes"]
    assert [(r["scene"], r["method"]) for r in rows] == [
        ("scene_0000", "cuboids"),
        ("scene_0000", "baseline"),
        ("scene_0001", "cuboids"),
        ("scene_0001", "baseline"),
    ]
    for r in rows:
        assert set(KEYS) <= set(r) and r["seconds"] > 0.0, r
    fitted = [r for r in rows if r["method"] == "cuboids"]
    assert all(r["auc20cm_pct"] > 50.0 and 1 <= r["n_cuboids"] <= 8 for r in fitted), fitted
    assert all(r["n_cuboids"] > 0 for r in rows if r["method"] == "baseline")
    agg = doc["aggregate"]
    assert set(agg) == {"cuboids", "baseline"} and agg["cuboids"]["scenes"] == 2
    assert agg["cuboids"]["auc20cm_pct"] == pytest.approx(np.mean([r["auc20cm_pct"] for r in fitted]))
    # recalls are pooled over the rooms' boxes
    matched = sum(r["shell_matches_iou0.25"] for r in fitted)
    gt_shell = sum(r["gt_shell"] for r in fitted)
    assert agg["cuboids"]["shell_box_recall_iou0.25_pct"] == pytest.approx(100.0 * matched / gt_shell)
    # the floor and walls are found in their planes, though the fitted slabs are far thinner than the truth's
    assert matched > 0


def test_one_scan_as_a_bare_cloud(app, rooms, tmp_path):
    out = tmp_path / "bare"
    quick = [*QUICK[:1], "4", *QUICK[2:]]
    result = run_evaluate(app, rooms / "scene_0001", "--bare", "--visibility", "inside", "-o", out, *quick)
    assert result.exit_code == 0, result.output
    assert "1 room scan:" in result.output and "cuboids (inside, bare cloud)" in result.output
    assert "planes+clusters" not in result.output
    doc = json.loads((out / "scenes.json").read_text())
    assert doc["settings"]["bare"] is True and doc["settings"]["fit"]["visibility"] == "inside"
    (row,) = doc["scenes"]
    assert row["scene"] == "scene_0001" and row["method"] == "cuboids" and 1 <= row["n_cuboids"] <= 4


def test_bare_fits_the_fused_points_without_their_cameras(rooms):
    """--bare is the library call Fitter.fit(fused points): an (N, 3) array, a room without its cameras
    (no viewpoints, no up hint), with the fitter's own settings and parts."""
    calls = []

    class Info:
        visibility = "views"

    class Result:
        cuboids, objects, info = [], [], Info()

    class Fitter:
        config = FitConfig()

        def fit(self, x, *args, **kwargs):
            calls.append((x, args, kwargs))
            return Result()

        def fit_input(self, *args, **kwargs):
            raise AssertionError("a bare cloud is fitted without its cameras")

    settings = scene_run.SceneEvalSettings(bare=True)
    rows, visibility = scene_run.evaluate_scene(rooms / "scene_0000", Fitter(), settings)
    ((points, args, kwargs),) = calls
    assert isinstance(points, np.ndarray) and points.shape[1] == 3
    assert np.array_equal(points, load(rooms / "scene_0000").points) and args == () and kwargs == {}
    assert visibility == "views" and rows[0]["n_cuboids"] == 0 and rows[0]["auc20cm_pct"] == 0.0


def test_scan_folders_are_found(rooms):
    names = [p.name for p in scene_run.scene_folders(rooms)]
    assert names == ["scene_0000", "scene_0001"]  # "notes" is no scan
    assert scene_run.scene_folders(rooms / "scene_0001") == [rooms / "scene_0001"]
    assert scene_run.scene_folders(rooms / "notes") == [] and scene_run.scene_folders(rooms / "none") == []


def test_a_folder_without_scans(app, tmp_path):
    (tmp_path / "empty").mkdir()
    text = one_line_error(run_evaluate(app, tmp_path / "empty", "--baseline"))
    assert "no room scans" in text and "scene_*/" in text
    # a scan cut short before its ground truth was written
    (tmp_path / "cut" / "scene_0000").mkdir(parents=True)
    (tmp_path / "cut" / "scene_0000" / "gt.json").write_text("{}")
    text = one_line_error(run_evaluate(app, tmp_path / "cut"))
    assert "not a complete room scan" in text and "truth_points.npz" in text


def test_an_unreadable_scan(app, tmp_path):
    scan = tmp_path / "bad" / "scene_0000"
    scan.mkdir(parents=True)
    (scan / "gt.json").write_text("not json")
    (scan / "truth_points.npz").write_bytes(b"not npz")
    text = one_line_error(run_evaluate(app, tmp_path / "bad", *QUICK))
    assert "cannot read its ground truth" in text


@pytest.mark.parametrize(
    "args, message",
    [
        (["--runs", "2"], "--runs applies to frames"),
        (["--rgb"], "--rgb applies to frames"),
        (["--auc", "10"], "--auc applies to frames"),
        (["--visibility", "sideways"], "--visibility 'sideways'"),
        (["--sampler", "learned"], "learned sampler"),
        (["--limit", "0"], "--limit must be at least 1"),
    ],
)
def test_bad_options_in_one_line(app, rooms, args, message):
    assert message in one_line_error(run_evaluate(app, rooms, *args))


def test_output_must_be_a_folder(app, rooms, tmp_path):
    target = tmp_path / "file.json"
    target.write_text("x")
    assert "is a file" in one_line_error(run_evaluate(app, rooms, "-o", target))

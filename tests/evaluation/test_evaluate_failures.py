"""`cuboids evaluate` on a dataset with a corrupt and a missing frame, and fits that find no cuboid."""

from __future__ import annotations

import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from cuboidcli.cli.main import app
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.aggregate import aggregate
from cuboidcli.evaluation.metrics import frame_metrics
from cuboidcli.evaluation.raycast import render_depth
from cuboidcli.evaluation.runner import EvalSettings, MissingFrame, evaluate, load_frames
from cuboidcli.fitting.config import FitConfig
from tests.evaluation.test_evaluate import CAM, FAST_OPTS, SMALL, make_folder


@pytest.fixture()
def damaged(tmp_path):
    """Four frames f0..f3; f1's depth PNG is cut short and splits.json names a frame f9 without files."""
    root = tmp_path / "data"
    names = make_folder(root, n=4)
    png = root / "depth" / "f1.png"
    png.write_bytes(png.read_bytes()[:200])
    (root / "splits.json").write_text(json.dumps({"test": [*names, "f9"]}))
    return root


def test_bad_frames_are_listed_and_the_others_scored(damaged, tmp_path):
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["evaluate", str(damaged), "--split", "test", "-o", str(out), *FAST_OPTS])
    assert res.exit_code == 1, res.output
    assert "Traceback" not in res.output and "WARN" not in res.output
    failed_lines = [line for line in res.stderr.splitlines() if line.startswith("failed")]
    assert len(failed_lines) == 2
    assert "f1" in failed_lines[0] and "cannot decode" in failed_lines[0]
    assert "f9" in failed_lines[1] and "no depth map" in failed_lines[1]
    assert "error: 2 of 5 frames could not be evaluated" in res.stderr
    assert "3 frames" in res.stdout  # the table covers the frames that were scored
    doc = json.loads((out / "metrics.json").read_text())
    assert [(f["frame"], f["seed"]) for f in doc["failed_frames"]] == [("f1", 0), ("f9", 0)]
    assert doc["runs"][0]["frames"] == 3 and doc["runs"][0]["frames_failed"] == 2
    assert [row["frame"] for row in doc["frames"]] == ["f0", "f2", "f3"]
    # the scored frames give exactly the numbers they give alone
    good, _ = load_frames(damaged, names=["f0", "f2", "f3"])
    alone = evaluate(good, SMALL, EvalSettings())
    assert doc["runs"][0]["oa_all_cm"] == pytest.approx(alone.runs[0]["oa_all_cm"], rel=1e-9)
    assert doc["runs"][0]["auc20cm_pct"] == pytest.approx(alone.runs[0]["auc20cm_pct"], rel=1e-9)


def test_missing_frames_come_from_the_split(damaged):
    frames, _ = load_frames(damaged, split="test")
    assert [f.name for f in frames] == ["f0", "f1", "f2", "f3", "f9"]
    assert isinstance(frames[-1], MissingFrame)
    report = evaluate(frames, SMALL, EvalSettings(runs=2))
    assert [(f["frame"], f["seed"]) for f in report.failures] == [("f1", 0), ("f9", 0), ("f1", 1), ("f9", 1)]
    assert all(r["frames"] == 3 and r["frames_failed"] == 2 for r in report.runs)


def test_a_fit_without_cuboids_counts_with_zero_recall_everywhere():
    room = Cuboid([0.0, -0.2, 2.5], [2.5, 1.5, 3.0], np.eye(3))
    box = Cuboid([0.3, 0.9, 3.0], [0.5, 0.4, 0.4], np.eye(3))
    depth = render_depth(CAM, [room, box])
    instances = np.where(np.abs(depth - 2.6) < 0.45, 2, 1).astype(np.int32)  # the box in front, the room
    empty = frame_metrics("e", depth, CAM, [], gt=[room, box], instances=instances, parsimony_k=3)
    row = empty.row()
    assert row["recall_iou0.25_pct"] == 0.0 and row["recall_iou0.5_pct"] == 0.0
    assert row["object_recall_pct"] == 0.0 and empty.objects.eligible == 2
    assert row["auc20cm_pct"] == 0.0 and row["auc5cm_pct"] == 0.0
    assert all(s.value == 0.0 for curve in empty.prefix_auc.values() for s in curve)
    assert math.isfinite(empty.oa_all_m) and empty.oa_all_m > float(depth[depth > 0].mean())
    exact = frame_metrics("x", depth, CAM, [room, box], gt=[room, box], instances=instances)
    agg = aggregate([exact, empty])
    assert agg["frames_without_cuboids"] == 1
    assert agg["oa_all_cm"] == pytest.approx(50.0 * (exact.oa_all_m + empty.oa_all_m), rel=1e-9)
    assert agg["recall_iou0.5_pct"] == pytest.approx(50.0)  # 2 of the 4 ground-truth boxes are found
    assert agg["object_recall_pct"] == pytest.approx(100.0 * exact.objects.explained / 4)
    assert agg["auc5cm_pct"] == pytest.approx(exact.row()["auc5cm_pct"] / 2, rel=1e-9)


def test_an_empty_fit_in_the_runner_is_scored_not_dropped(tmp_path):
    """A Theta no cuboid reaches: every frame gets no cuboid and all of them are in the OA means."""
    root = tmp_path / "data"
    make_folder(root, n=2)
    frames, _ = load_frames(root)
    report = evaluate(frames, FitConfig(hypotheses=16, max_cuboids=1, grid_step=4, theta=1e9), EvalSettings())
    run = report.runs[0]
    assert run["frames"] == 2 and run["frames_without_cuboids"] == 2 and run["cuboids"] == 0.0
    assert math.isfinite(run["oa_all_cm"]) and run["oa_all_cm"] > 100.0
    assert run["auc20cm_pct"] == 0.0 and run["recall_iou0.25_pct"] == 0.0

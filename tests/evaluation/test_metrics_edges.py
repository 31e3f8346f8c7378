"""Edge cases and reporting units of the metrics (written against the survivors of scripts/mutation.sh):
single distances and exact thresholds in AUC, pooling identities, object counting at its 1 % and 50 %
boundaries, the per-frame row in cm and %, and aggregates of runs of different lengths."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.aggregate import aggregate, mean_std, parsimony_curve
from cuboidcli.evaluation.auc import AucStats, auc
from cuboidcli.evaluation.metrics import FrameMetrics, frame_metrics
from cuboidcli.evaluation.object_recall import ObjectCounts, object_counts
from cuboidcli.evaluation.raycast import render_depth

CAM = Camera.preset("nyu").scaled(0.125)  # 80x60


def test_auc_of_one_distance_and_at_the_threshold():
    assert auc(np.array([0.05]), 0.2) == pytest.approx(0.75)  # recall 1 from 5 cm to 20 cm
    assert AucStats.of(np.array([0.05]), 0.2).value == pytest.approx(0.75)
    assert auc(np.array([]), 0.2) == 0.0 and AucStats.of(np.array([]), 0.2).value == 0.0
    # a distance exactly at X still counts: (0.1, 1/2), (0.2, 1), cut at 0.2 -> 0.075 / 0.2
    d = np.array([0.1, 0.2])
    assert auc(d, 0.2) == pytest.approx(0.375) and AucStats.of(d, 0.2).value == pytest.approx(0.375)


def test_empty_statistics_are_the_identity_of_pooling():
    empty = AucStats(0.2)
    assert empty.value == 0.0
    s = AucStats.of(np.array([0.01, 0.07, 0.5]), 0.2)
    merged = empty.merge(s)
    assert (merged.n, merged.excess_sum, merged.d_first, merged.d_last) == (s.n, s.excess_sum, 0.01, 0.07)


def test_object_counts_small_frames_and_boundaries():
    assert object_counts(np.zeros(0, int), np.zeros(0, int), 3) == ObjectCounts(0, 0, 0, 3)
    # one point, one object, one cuboid that holds it
    assert object_counts(np.array([0]), np.array([4]), 1) == ObjectCounts(1, 1, 1, 1)
    # one-point objects are explained by the cuboid that holds just them
    assert object_counts(np.array([0, 1, 1]), np.array([1, 2, 2]), 2) == ObjectCounts(2, 2, 2, 2)
    # eligibility needs 1 % of the points: 1 of 101 is not enough, 1 of 100 is
    ids = np.zeros(101, int)
    ids[0] = 5
    assert object_counts(np.full(101, -1), ids, 1).eligible == 0
    assert object_counts(np.full(100, -1), ids[:100], 1).eligible == 1
    # a cuboid must hold at least half of the object: 50 of 101 points is not enough, 51 is
    ids = np.full(101, 3)
    labels = np.full(101, -1)
    labels[:50] = 0
    assert object_counts(labels, ids, 1) == ObjectCounts(0, 1, 0, 1)
    labels[50] = 0
    assert object_counts(labels, ids, 1) == ObjectCounts(1, 1, 1, 1)


def _row_frame(**kw) -> FrameMetrics:
    base = dict(
        name="f",
        cuboids=2,
        coverage=0.25,
        oa_all_m=0.05,
        oa_covered_m=0.031,
        n_points=400,
        n_covered_points=100,
        auc={20.0: AucStats.of(np.array([0.05]), 0.2)},
        gt_matches={0.25: (1, 4, 2), 0.5: (0, 0, 2)},
    )
    return FrameMetrics(**{**base, **kw})


def test_frame_row_in_reporting_units():
    r = _row_frame().row()
    assert r["coverage_pct"] == pytest.approx(25.0)
    assert r["oa_covered_cm"] == pytest.approx(3.1) and r["oa_all_cm"] == pytest.approx(5.0)
    assert r["auc20cm_pct"] == pytest.approx(75.0)
    assert r["recall_iou0.25_pct"] == pytest.approx(25.0)
    assert r["precision_iou0.25_pct"] == pytest.approx(50.0)
    assert math.isnan(r["recall_iou0.5_pct"]) and r["precision_iou0.5_pct"] == 0.0
    assert (r["points"], r["covered_points"]) == (400, 100)


def test_aggregate_of_nothing_and_pooled_precision():
    assert aggregate([]) == {"frames": 0}
    agg = aggregate([_row_frame(), _row_frame(gt_matches={0.25: (2, 2, 3), 0.5: (0, 0, 2)})])
    assert agg["recall_iou0.25_pct"] == pytest.approx(100.0 * 3 / 6)
    assert agg["precision_iou0.25_pct"] == pytest.approx(100.0 * 3 / 5)


def test_frame_counts_covered_points_and_curve_length():
    wall = Cuboid([0.0, 0.0, 3.05], [5.0, 5.0, 0.05], np.eye(3))
    depth = render_depth(CAM, [wall])
    m = frame_metrics("w", depth, CAM, [wall], parsimony_k=1)
    assert m.n_covered_points == m.n_points == CAM.width * CAM.height
    assert len(m.prefix_coverage) == 1 and len(m.prefix_auc[20.0]) == 1
    curve = parsimony_curve([m])  # a single frame
    assert curve["k"] == [1] and curve["coverage_pct"] == [pytest.approx(100.0)]


def test_mean_and_std_of_parsimony_curves_of_different_lengths():
    runs = [
        {"frames": 1, "parsimony": {"k": [1, 2], "coverage_pct": [10.0, 20.0]}},
        {"frames": 1, "parsimony": {"k": [1, 2, 3], "coverage_pct": [30.0, 40.0, 50.0]}},
    ]
    mean, std = mean_std(runs)["parsimony"]
    assert mean["k"] == std["k"] == [1, 2, 3]
    assert mean["coverage_pct"] == pytest.approx([20.0, 30.0, 35.0])  # the shorter run padded with 20
    assert std["coverage_pct"] == pytest.approx([10.0, 10.0, 15.0])

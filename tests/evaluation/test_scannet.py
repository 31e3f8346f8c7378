"""Scoring real scans with labelled boxes (cuboidcli.evaluation.scannet) on a tiny ScanNet-style folder
written here: a floor, a wall, a cabinet and a table, each with its instance and class."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.scannet import (
    ScanFit,
    ScanTruth,
    average_precision,
    detection_hits,
    on_one_object,
    pool_rows,
    read_truth,
    scan_fit,
    scan_input,
    scan_metrics,
    scan_names,
)
from tests.conftest import SHARED_DATA

CABINET = (np.array([0.5, 1.0, 0.5]), np.array([0.6, 1.2, 1.0]), 3)
TABLE = (np.array([2.5, 1.5, 0.375]), np.array([1.2, 0.8, 0.75]), 7)


def _box_surface(rng, center, size, n):
    """n points on the faces of an axis-aligned box, floor face left out."""
    pts = rng.uniform(-0.5, 0.5, (n, 3)) * size
    face = rng.integers(0, 5, n)  # +-x, +-y, +z
    axis, sign = np.array([0, 0, 1, 1, 2])[face], np.array([1, -1, 1, -1, 1])[face]
    pts[np.arange(n), axis] = sign * size[axis] / 2
    return pts + center


def write_scan(folder, name="scene0000_00", seed=0):
    """A 4 x 3 m room: floor (instance 1, class 2), wall y = 3 (2, class 1), cabinet (3, class 3), table (4,
    class 7); the points as ``_vert.npy`` with colours, the two furniture boxes as ``_bbox.npy``."""
    rng = np.random.default_rng(seed)
    floor = np.c_[rng.uniform(0, 4, (3000, 2)), np.zeros(3000)]
    wall = np.c_[rng.uniform(0, 4, 2000), np.full(2000, 3.0), rng.uniform(0, 2.5, 2000)]
    parts = [floor, wall, _box_surface(rng, *CABINET[:2], 1500), _box_surface(rng, *TABLE[:2], 1500)]
    points = np.concatenate(parts)
    instance = np.repeat([1, 2, 3, 4], [len(p) for p in parts]).astype(np.uint32)
    semantic = np.repeat([2, 1, 3, 7], [len(p) for p in parts]).astype(np.uint32)
    colors = rng.uniform(0, 255, (len(points), 3))
    np.save(folder / f"{name}_vert.npy", np.c_[points, colors].astype(np.float32))
    np.save(folder / f"{name}_ins_label.npy", instance)
    np.save(folder / f"{name}_sem_label.npy", semantic)
    np.save(folder / f"{name}_bbox.npy", np.array([[*c, *s, k] for c, s, k in (CABINET, TABLE)]))


@pytest.fixture
def scan(tmp_path):
    write_scan(tmp_path)
    return read_truth(tmp_path, "scene0000_00")


def _fit(boxes, scores=None, cuboids=None):
    scores = np.linspace(1.0, 0.5, len(boxes)) if scores is None else np.asarray(scores, dtype=np.float64)
    return ScanFit(cuboids or [], list(boxes), scores, np.array([0.0, 0.0, 1.0]), 1.0)


def _shifted(box: Cuboid, dx: float) -> Cuboid:
    return Cuboid(box.center + [dx, 0.0, 0.0], box.half_size, box.rotation, kind="object")


def test_a_folder_lists_its_scans_and_reads_their_labels(tmp_path, scan):
    (tmp_path / "notes_bbox.txt").write_text("not a scan")
    assert scan_names(tmp_path) == ["scene0000_00"]
    assert scan_input(tmp_path, "scene0000_00").name == "scene0000_00_vert.npy"
    assert len(scan.boxes) == 2 and list(scan.classes) == [3, 7]
    np.testing.assert_allclose(scan.boxes[1].half_size, TABLE[1] / 2)
    assert len(scan.points) == len(scan.instance) == 8000


def test_the_labelled_floor_faces_the_room_whichever_way_the_file_is_stored(tmp_path, scan):
    np.testing.assert_allclose(scan.up, [0.0, 0.0, 1.0], atol=1e-6)
    vert = np.load(tmp_path / "scene0000_00_vert.npy")
    for turn, up in (((1.0, -1.0, -1.0), (0.0, 0.0, -1.0)), ((1.0, 1.0, 1.0), (0.0, 0.0, 1.0))):
        np.save(tmp_path / "scene0000_00_vert.npy", vert * np.array([*turn, 1.0, 1.0, 1.0], np.float32))
        np.testing.assert_allclose(read_truth(tmp_path, "scene0000_00").up, up, atol=1e-6)
    yup = vert.copy()
    yup[:, [1, 2]] = vert[:, [2, 1]]  # stored y up
    np.save(tmp_path / "scene0000_00_vert.npy", yup)
    np.testing.assert_allclose(read_truth(tmp_path, "scene0000_00").up, [0.0, 1.0, 0.0], atol=1e-6)


def test_the_labelled_boxes_themselves_score_full_marks(scan):
    row = scan_metrics(_fit(scan.boxes, cuboids=scan.boxes), scan)
    for key in (
        "recall_iou0.25_pct",
        "recall_iou0.5_pct",
        "ap_iou0.25_pct",
        "ap_iou0.5_pct",
        "precision_pct",
    ):
        assert row[key] == pytest.approx(100.0), key
    assert row["class_labelled"] == {"cabinet": 1, "table": 1} == row["class_matched"]
    assert row["up_error_deg"] == pytest.approx(0.0)


def test_a_shifted_box_loses_the_stricter_iou_first(scan):
    cabinet, table = scan.boxes
    # the table shifted by 40 % of its length: IoU (0.6 / 1.4) = 0.43, between the two thresholds
    row = scan_metrics(_fit([cabinet, _shifted(table, 0.48)]), scan)
    assert row["recall_iou0.25_pct"] == 100.0 and row["recall_iou0.5_pct"] == 50.0
    assert row["ap_iou0.5_pct"] == pytest.approx(50.0)
    far = scan_metrics(_fit([cabinet, _shifted(table, 1.0)]), scan)
    assert far["recall_iou0.25_pct"] == 50.0 and far["class_matched"] == {"cabinet": 1, "table": 0}


def test_ap_falls_when_a_false_box_outranks_the_true_ones():
    # three labelled boxes, four predictions: hits at ranks 2, 3, 4 by score
    scores = np.array([0.9, 0.8, 0.7, 0.6])
    hits = np.array([False, True, True, True])
    # precision at recall 1/3, 2/3, 1: 1/2, 2/3, 3/4, made monotone: 3/4 everywhere
    assert average_precision(scores, hits, 3) == pytest.approx(0.75)
    assert average_precision(scores, hits[::-1], 3) == pytest.approx(1.0)  # the false box last
    assert average_precision(scores, hits, 4) == pytest.approx(0.5625)
    assert average_precision(np.zeros(0), np.zeros(0, dtype=bool), 2) == 0.0
    assert math.isnan(average_precision(scores, hits, 0))


def test_a_second_box_on_a_taken_object_is_a_false_hit():
    ious = np.array([[0.9], [0.8], [0.1]])
    assert list(detection_hits(ious, np.array([0.5, 0.9, 0.1]), 0.25)) == [False, True, False]


def test_precision_counts_boxes_on_one_labelled_object(scan):
    cabinet, table = scan.boxes
    both = Cuboid([1.5, 1.25, 0.5], [1.5, 0.7, 0.5], np.eye(3), kind="object")  # over cabinet and table
    on_wall = Cuboid([2.0, 3.0, 1.5], [1.0, 0.05, 0.5], np.eye(3), kind="object")
    cabinet_side = Cuboid([0.5, 0.45, 0.5], [0.35, 0.1, 0.5], np.eye(3), kind="object")
    empty = Cuboid([2.0, 1.0, 2.0], [0.1, 0.1, 0.1], np.eye(3), kind="object")
    assert list(on_one_object([cabinet, both, on_wall, cabinet_side, empty], scan)) == [
        True, False, False, True, False,
    ]  # fmt: skip
    row = scan_metrics(_fit([cabinet, both, on_wall, cabinet_side]), scan)
    assert row["precision_pct"] == 50.0 and row["objects"] == 4


def test_pooled_rates_come_from_the_summed_counts(tmp_path, scan):
    write_scan(tmp_path, "scene0001_00", seed=1)
    other = read_truth(tmp_path, "scene0001_00")
    cabinet, table = scan.boxes
    rows = [
        scan_metrics(_fit([cabinet, table]), scan),
        scan_metrics(_fit([_shifted(cabinet, -2.0)], scores=[0.99]), other),
    ]
    pooled = pool_rows(rows)
    assert pooled["recall_iou0.25_pct"] == 50.0 and pooled["labelled"] == 2.0
    assert pooled["precision_pct"] == pytest.approx(200.0 / 3.0)
    # ranked 1.0 (hit), 0.99 (the false box outside the room), 0.5 (hit): precision 1 up to recall 1/4,
    # then 2/3 up to 1/2
    assert pooled["ap_iou0.25_pct"] == pytest.approx(100.0 * (0.25 + 0.25 * 2 / 3))
    assert pooled["class_labelled"] == {"cabinet": 2, "table": 2}
    assert pooled["class_matched"] == {"cabinet": 1, "table": 1}


def test_a_result_document_gives_its_boxes_scores_and_up():
    doc = {
        "cuboids": [{"kind": "floor", "center": [0, 0, 0], "half_size": [2, 2, 0.01], "rotation": np.eye(3)}],
        "objects": [
            {
                "id": 0,
                "center": [1, 1, 0.5],
                "half_size": [0.3, 0.3, 0.5],
                "rotation": np.eye(3),
                "score": 0.8,
            },
            {"id": 1, "center": [2, 1, 0.5], "half_size": [0.3, 0.3, 0.5], "rotation": np.eye(3)},
        ],
        "up": {"up": [0.0, -1.0, 0.0]},
        "fit_info": {"stop_reason": "max_cuboids"},
    }
    fit = scan_fit(doc, 2.5)
    assert [c.kind for c in fit.cuboids] == ["floor"] and len(fit.objects) == 2
    assert list(fit.scores) == [0.8, 0.0] and fit.stop_reason == "max_cuboids"
    unlabelled = ScanTruth("empty", np.zeros((1, 3)), [], np.zeros(0, dtype=np.int64), None, None)
    row = scan_metrics(fit, unlabelled)
    assert row["up_error_deg"] == pytest.approx(90.0)
    assert math.isnan(row["recall_iou0.25_pct"]) and math.isnan(row["precision_pct"])


SCANNET = SHARED_DATA / "scannet"


@pytest.mark.skipif(not (SCANNET / "scene0001_00_bbox.npy").is_file(), reason="no shared ScanNet scans")
def test_a_real_scan_s_labelled_boxes_lie_on_their_instances():
    truth = read_truth(SCANNET, "scene0001_00")
    assert len(truth.points) == 50000 and len(truth.boxes) == 17
    # the labels agree with each other: each labelled box is mostly the points of one labelled instance
    assert on_one_object(truth.boxes, truth).mean() >= 0.8
    row = scan_metrics(_fit(truth.boxes), truth)
    assert row["recall_iou0.5_pct"] == 100.0 and row["ap_iou0.5_pct"] == pytest.approx(100.0)
    assert sum(row["class_labelled"].values()) == 17

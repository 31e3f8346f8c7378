"""Object recall / precision of `cuboids evaluate` (instance images of synthetic frames), on rendered scenes
with known objects and on hand-made assignments."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.aggregate import aggregate
from cuboidcli.evaluation.metrics import frame_metrics
from cuboidcli.evaluation.object_recall import ObjectCounts, object_counts
from cuboidcli.fitting.config import FitConfig
from cuboidcli.synth.render import render_boxes
from tests.conftest import simple_room

CAM = Camera.preset("nyu").scaled(0.25)  # 160x120


@pytest.fixture(scope="module")
def room():
    """Depth and instance image (1 + box index) of the five objects of simple_room, rendered exactly."""
    boxes = simple_room()
    depth, instances = render_boxes(boxes, CAM)
    return boxes, depth, instances


def objects_of(depth, instances, cuboids, config=None):
    m = frame_metrics("f", depth, CAM, cuboids, instances=instances, config=config)
    return m, m.objects


# ---------------------------------------------------------------- rendered scenes


def test_every_object_of_the_room_is_eligible(room):
    boxes, depth, instances = room
    valid = depth > 0
    sizes = np.bincount(instances[valid], minlength=len(boxes) + 1)[1:]
    assert (sizes >= 0.01 * valid.sum()).all()  # five eligible objects: the tests below rely on it


def test_perfect_prediction_explains_every_object(room):
    boxes, depth, instances = room
    m, counts = objects_of(depth, instances, boxes)
    assert counts == ObjectCounts(explained=5, eligible=5, explaining=5, predicted=5)
    row = m.row()
    assert row["object_recall_pct"] == 100.0 and row["object_precision_pct"] == 100.0
    assert row["objects_eligible"] == 5


def test_missing_object_lowers_recall_by_one_over_eligible(room):
    boxes, depth, instances = room
    without_cabinet = [b for b in boxes if b.extras.get("category") != "cabinet"]
    m, counts = objects_of(depth, instances, without_cabinet)
    assert counts == ObjectCounts(explained=4, eligible=5, explaining=4, predicted=4)
    assert m.row()["object_recall_pct"] == pytest.approx(100.0 * (1 - 1 / 5))
    assert m.row()["object_precision_pct"] == 100.0


def test_extra_cuboid_on_nothing_lowers_precision_only(room):
    boxes, depth, instances = room
    far_away = Cuboid([6.0, 0.0, 3.0], [0.5, 0.5, 0.5], np.eye(3))  # outside the room, hides nothing
    m, counts = objects_of(depth, instances, boxes + [far_away])
    assert counts == ObjectCounts(explained=5, eligible=5, explaining=5, predicted=6)
    assert m.row()["object_recall_pct"] == 100.0
    assert m.row()["object_precision_pct"] == pytest.approx(100.0 * 5 / 6)


def test_no_prediction_explains_nothing(room):
    _, depth, instances = room
    m, counts = objects_of(depth, instances, [])
    assert counts == ObjectCounts(explained=0, eligible=5, explaining=0, predicted=0)
    assert m.row()["object_recall_pct"] == 0.0 and math.isnan(m.row()["object_precision_pct"])


def test_cuboid_straddling_two_objects_half_half_explains_neither():
    """A wall and two equal boxes standing side by side in front of it. The wall is predicted exactly; one
    cuboid sits across the gap between the boxes, over the inner 40 % of each: half of its points lie on
    each box and it holds less than half of either, so it explains neither."""
    eye = np.eye(3)
    wall = Cuboid([0.0, 0.0, 4.05], [3.0, 2.5, 0.05], eye)
    left = Cuboid([-0.55, 0.0, 3.0], [0.5, 0.5, 0.5], eye)
    right = Cuboid([0.55, 0.0, 3.0], [0.5, 0.5, 0.5], eye)
    depth, instances = render_boxes([wall, left, right], CAM)
    # x from -0.45 (60 % into the left box's width of 1 m) to +0.45; same depth range as the boxes
    straddle = Cuboid([0.0, 0.0, 3.0], [0.45, 0.5, 0.5], eye)
    m, counts = objects_of(depth, instances, [wall, straddle])
    assert counts == ObjectCounts(explained=1, eligible=3, explaining=1, predicted=2)
    assert m.row()["object_recall_pct"] == pytest.approx(100 / 3)
    assert m.row()["object_precision_pct"] == 50.0
    # the same scene with the two boxes predicted exactly: everything explained
    _, exact = objects_of(depth, instances, [wall, left, right])
    assert exact == ObjectCounts(3, 3, 3, 3)


def test_assignment_follows_the_config_tau(room):
    """A box predicted 10 cm too far back: its points lie beyond tau = 0.004 m^2 (6.3 cm), within 0.04 m^2."""
    boxes, depth, instances = room
    cabinet = next(i for i, b in enumerate(boxes) if b.extras.get("category") == "cabinet")
    shifted = list(boxes)
    b = boxes[cabinet]
    shifted[cabinet] = Cuboid(b.center + [0.0, 0.0, 0.1], b.half_size, b.rotation)
    _, tight = objects_of(depth, instances, shifted, FitConfig())
    _, loose = objects_of(depth, instances, shifted, FitConfig(tau_sq_m2=0.04))
    assert tight.explained == 4 and loose.explained == 5


def test_objects_pooled_over_frames(room):
    boxes, depth, instances = room
    full = frame_metrics("a", depth, CAM, boxes, instances=instances)
    fewer = frame_metrics("b", depth, CAM, boxes[:3], instances=instances)
    plain = frame_metrics("c", depth, CAM, boxes)  # no instance image: left out of the object numbers
    agg = aggregate([full, fewer, plain])
    assert agg["object_recall_pct"] == pytest.approx(100.0 * (5 + 3) / (5 + 5))
    assert agg["object_precision_pct"] == pytest.approx(100.0)
    assert agg["objects_eligible"] == 10 and agg["frames_with_instances"] == 2
    no_instances = aggregate([plain])
    assert "object_recall_pct" not in no_instances and "frames_with_instances" not in no_instances
    assert "object_recall_pct" not in plain.row()


def test_instance_image_of_another_size_is_refused(room):
    boxes, depth, instances = room
    with pytest.raises(ValueError, match="instance image"):
        frame_metrics("f", depth, CAM, boxes, instances=instances[:-1])


# ---------------------------------------------------------------- thresholds on hand-made assignments


def test_object_counts_thresholds_are_inclusive_and_exact():
    # 200 valid points: object 1 has 100, object 2 has 2 (1 %: eligible), object 3 has 1 (0.5 %), 97 none
    ids = np.array([1] * 100 + [2] * 2 + [3] * 1 + [0] * 97)
    labels = np.full(200, -1)
    labels[:50] = 0  # cuboid 0 holds exactly 50 % of object 1 ...
    labels[103:153] = 0  # ... and 50 background points: exactly 50 % of its points on the object
    labels[100:102] = 1  # cuboid 1 holds object 2 entirely
    labels[102] = 2  # cuboid 2 holds the ineligible object 3
    counts = object_counts(labels, ids, 3)
    assert counts == ObjectCounts(explained=2, eligible=2, explaining=2, predicted=3)
    labels[153] = 0  # one more background point: cuboid 0 is no longer pure enough
    assert object_counts(labels, ids, 3) == ObjectCounts(1, 2, 1, 3)
    labels[153] = -2  # occluded points belong to no cuboid
    labels[50] = -2
    assert object_counts(labels, ids, 3) == ObjectCounts(2, 2, 2, 3)
    labels[49] = -1  # 49 % of object 1 held: not explained
    assert object_counts(labels, ids, 3) == ObjectCounts(1, 2, 1, 3)


def test_object_counts_large_ids_and_one_cuboid_for_two_objects():
    ids = np.array([60000] * 30 + [7] * 30 + [0] * 40, dtype=np.uint16)
    labels = np.array([0] * 60 + [-1] * 40)  # one cuboid over both objects: 50 % purity each, a tie
    assert object_counts(labels, ids, 1) == ObjectCounts(explained=2, eligible=2, explaining=1, predicted=1)
    labels[:5] = -1  # 25 vs 30 points: only object 7 keeps a majority of the cuboid's points
    assert object_counts(labels, ids, 1) == ObjectCounts(explained=1, eligible=2, explaining=1, predicted=1)

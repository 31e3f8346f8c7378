"""Object boxes that several fits of a room agree on (fitting/consensus.py); the setting that asks for the
fits (``FitConfig.object_fits``)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.iou import box_iou
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.consensus import agreed_objects, upright_iou
from cuboidcli.fitting.objects import SceneObject
from cuboidcli.geometry.gravity import level_frame

UP = np.array([0.0, 0.0, 1.0])
R = level_frame(UP)


def _yaw(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _box(x, y, z=0.4, size=(1.0, 0.6, 0.8), yaw=0.0) -> Cuboid:
    return Cuboid(np.array([x, y, z]), np.asarray(size, dtype=float) / 2, _yaw(yaw), kind="object")


def _obj(box: Cuboid, score: float = 0.5, cuboids=(3,), points: int = 100) -> SceneObject:
    return SceneObject(box, tuple(cuboids), points, score)


def test_the_upright_iou_is_the_exact_iou_of_the_boxes():
    rng = np.random.default_rng(0)
    for _ in range(40):
        a, b = (_box(*rng.uniform(-0.3, 0.3, 2), *rng.uniform(0.3, 0.6, 1), rng.uniform(0.2, 1.2, 3),
                     *rng.uniform(-3, 3, 1)) for _ in range(2))  # fmt: skip
        assert upright_iou(a, b, R) == pytest.approx(box_iou(a, b), abs=1e-9)
    # a square and the same square turned 45 degrees: the octagon they share over the union
    square, turned = _box(0, 0, size=(1, 1, 1)), _box(0, 0, size=(1, 1, 1), yaw=math.pi / 4)
    octagon = 2.0 * (math.sqrt(2.0) - 1.0)
    assert upright_iou(square, turned, R) == pytest.approx(octagon / (2.0 - octagon))
    assert upright_iou(square, _box(0, 0, z=1.5, size=(1, 1, 1)), R) == 0.0  # one above the other
    assert upright_iou(square, _box(2, 0, size=(1, 1, 1)), R) == 0.0
    # the room's up need not be z: the same boxes turned with the room keep their IoU
    turn = level_frame(np.array([0.0, 1.0, 0.0])) @ R.T
    a, b = _box(0, 0, yaw=0.3), _box(0.3, 0.1, size=(0.8, 0.8, 0.5))
    moved = [Cuboid(turn @ c.center, c.half_size, turn @ c.rotation) for c in (a, b)]
    assert upright_iou(*moved, level_frame(turn @ UP)) == pytest.approx(upright_iou(a, b, R))


def test_a_box_most_fits_find_is_kept_and_one_fit_alone_is_not():
    table = [_box(0, 0), _box(0.05, 0, yaw=0.05), _box(0.1, 0.05)]
    scrap = _box(3, 3, size=(0.3, 0.3, 0.2))
    fits = [
        [_obj(table[0], 0.6), _obj(scrap, 0.9)],  # the first fit: a table and a scrap
        [_obj(table[1], 0.4, cuboids=(7,))],
        [_obj(table[2], 0.5, cuboids=(9,))],
    ]
    kept = agreed_objects(fits, R, need=2)
    assert len(kept) == 1
    # the box that agrees best with the others stands for it: the middle one, from the second fit; its
    # score scaled by the share of fits that found it; its cuboids the first fit's, the ones returned
    assert np.allclose(kept[0].box.center, table[1].center)
    assert kept[0].score == pytest.approx(0.4 * 3 / 3)
    assert kept[0].cuboids == (3,)
    # found by two fits of three, the first not among them: kept, with no cuboid of the first fit; of two
    # boxes the one looked at first (the higher score) stands for it
    fits = [[_obj(scrap)], [_obj(table[1], 0.4, cuboids=(7,))], [_obj(table[2], 0.5, cuboids=(9,))]]
    kept = agreed_objects(fits, R, need=2)
    assert len(kept) == 1 and kept[0].cuboids == () and kept[0].score == pytest.approx(0.5 * 2 / 3)
    assert np.allclose(kept[0].box.center, table[2].center)
    assert agreed_objects(fits, R, need=3) == []
    assert agreed_objects([[_obj(scrap)]], R, need=1)[0].box is scrap  # one fit keeps its own boxes


def test_each_fit_gives_an_object_one_box_and_a_box_serves_one_object():
    left, right = _box(0, 0), _box(1.05, 0)
    both = _box(0.5, 0, size=(2.1, 0.6, 0.8))  # one box over the two tables
    fits = [[_obj(left, 0.6), _obj(right, 0.5)], [_obj(both, 0.7)], [_obj(left), _obj(right)]]
    kept = agreed_objects(fits, R, need=2)
    # the box over both tables overlaps each at IoU 0.48: it votes for one table, not for both
    assert upright_iou(left, both, R) > 0.25 and upright_iou(right, both, R) > 0.25
    assert len(kept) == 2
    assert sorted(round(float(o.box.center[0]), 2) for o in kept) == [0.0, 1.05]
    # boxes that overlap under AGREE_IOU are other objects
    assert agreed_objects([[_obj(left)], [_obj(_box(0.8, 0))]], R, need=2) == []


def test_object_fits_is_a_room_setting():
    assert FitConfig().object_fits == 5
    assert "object_fits" in FitConfig().to_dict("room") and "object_fits" not in FitConfig().to_dict("frame")
    with pytest.raises(ValueError, match="object_fits"):
        FitConfig(object_fits=0).check(parts=False)


def test_a_fit_lends_its_most_overlapping_box_and_the_objects_come_most_points_first():
    table = _box(0, 0)
    near, nearer = _box(0.55, 0), _box(0.15, 0)  # IoU 0.29 and 0.74 with the table
    assert 0.25 < upright_iou(table, near, R) < 0.3 and upright_iou(table, nearer, R) > 0.7
    fits = [[_obj(table, 0.9, points=50)], [_obj(near, 0.1, points=70), _obj(nearer, 0.1, points=60)]]
    # the table takes the nearer box (of two it stands for itself, the one looked at first); the other box
    # of the second fit stays alone: kept when one fit is enough, most points first
    assert [o.points for o in agreed_objects(fits, R, need=1)] == [70, 50]
    assert [o.points for o in agreed_objects(fits, R, need=2)] == [50]
    # an overlap of 0.29 is enough to agree
    assert [o.points for o in agreed_objects([[_obj(table, points=50)], [_obj(near)]], R, need=2)] == [50]

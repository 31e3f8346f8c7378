"""Seats side by side under one back (cuboidcli.fitting.seats): two armchairs whose backs one cuboid explains
are two objects; one long seat or two cushions close together (a sofa) stay one; pieces that overlap, or of
an upright cuboid, split nothing."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.objects import group_objects
from cuboidcli.fitting.seats import is_level_slab, nearest_piece, pieces_inside
from tests.fitting.test_objects import VOXEL, _grid

UP = np.array([0.0, 0.0, 1.0])


WIDTH = 0.6  # a seat's width (m)


def _room(gap, parts, back):
    """A floor (cuboid 0), the ``back`` cuboid (1), two seats ``WIDTH`` wide and ``gap`` apart as pieces of
    one level cuboid (2), and ``parts`` [(points, label)]."""
    total = 2 * WIDTH + gap
    floor = _grid((-0.5, -0.5, 0), (2.5, 1.5, 0))
    seats = [_grid((x0, 0.0, 0.42), (x0 + WIDTH, 0.5, 0.42)) for x0 in (0.0, WIDTH + gap)]
    parts = [(floor, 0), *((seat, 2) for seat in seats), *parts]
    pts = np.concatenate([p for p, _ in parts])
    labels = np.concatenate([np.full(len(p), label) for p, label in parts]).astype(np.int32)
    cuboids = [
        Cuboid([1.0, 0.5, -0.02], [1.5, 1.0, 0.02], np.eye(3), kind="floor"),
        back,
        Cuboid([total / 2, 0.25, 0.42], [total / 2, 0.25, 0.01], np.eye(3), kind="object"),
    ]
    return pts, labels, cuboids


def _armchairs(gap):
    """Two armchairs side by side, ``gap`` apart: one cuboid (1) explains both backs and their arms (its
    inliers touch: one seed), and holds both seats (two seeds when they lie apart)."""
    total = 2 * WIDTH + gap
    back = _grid((0.0, 0.6, 0.45), (total, 0.6, 0.9))
    arms = [_grid((x, 0.0, 0.1), (x, 0.58, 0.65)) for x in (0.0, WIDTH + 0.03, WIDTH + gap - 0.03, total)]
    cuboid = Cuboid([total / 2, 0.31, 0.5], [total / 2, 0.31, 0.4], np.eye(3), kind="object")
    return _room(gap, [(back, 1), *((arm, 1) for arm in arms)], cuboid)


def test_two_armchairs_under_one_back_are_two_objects():
    objects = group_objects(*_armchairs(gap=0.2), UP, VOXEL)
    assert len(objects) == 2
    left, right = sorted(objects, key=lambda o: o.box.center[0])
    (l_lo, l_hi), (r_lo, r_hi) = ((o.box.corners().min(0), o.box.corners().max(0)) for o in (left, right))
    assert left.cuboids == right.cuboids == (1, 2)
    # the back over the 20 cm gap between the seats is shared at its middle (0.7 m)
    np.testing.assert_allclose([l_lo[0], l_hi[0], r_lo[0], r_hi[0]], [0.0, 0.7, 0.7, 1.4], atol=VOXEL)
    for lo, hi in ((l_lo, l_hi), (r_lo, r_hi)):
        assert lo[2] == 0.0 and abs(hi[2] - 0.9) <= VOXEL


@pytest.mark.parametrize("gap", [0.0, 0.08])
def test_one_sofa_under_its_back_is_one_object(gap):
    """One long seat, or two cushions whose gap the scan bridges in places, is one sofa."""
    (sofa,) = group_objects(*_armchairs(gap=gap), UP, VOXEL)
    lo, hi = sofa.box.corners().min(0), sofa.box.corners().max(0)
    assert abs(lo[0]) <= VOXEL and abs(hi[0] - (1.2 + gap)) <= VOXEL


def _chairs_before_one_back(gap):
    """Two chairs side by side, ``gap`` apart, on legs no cuboid explains; behind their seats one thin back
    (cuboid 1, its inliers only the back) whose box holds neither seat."""
    total = 2 * WIDTH + gap
    feet = (0.02, WIDTH - 0.02, WIDTH + gap + 0.02, total - 0.02)
    legs = [_grid((x, y, 0.05), (x, y, 0.4)) for x in feet for y in (0.02, 0.48)]
    back = _grid((0.0, 0.55, 0.45), (total, 0.55, 0.9))
    cuboid = Cuboid([total / 2, 0.55, 0.675], [total / 2, 0.01, 0.225], np.eye(3), kind="object")
    return _room(gap, [*((leg, -1) for leg in legs), (back, 1)], cuboid)


def test_two_chairs_before_one_back_are_two_objects():
    """The back's points go to the nearer seat: each chair is its seat, its legs and half of the back."""
    objects = group_objects(*_chairs_before_one_back(gap=0.2), UP, VOXEL)
    assert len(objects) == 2
    left, right = sorted(objects, key=lambda o: o.box.center[0])
    ends = [left.box.corners().min(0)[0], left.box.corners().max(0)[0], right.box.corners().min(0)[0]]
    np.testing.assert_allclose([*ends, right.box.corners().max(0)[0]], [0.0, 0.7, 0.7, 1.4], atol=VOXEL)
    for chair in (left, right):
        lo, hi = chair.box.corners().min(0), chair.box.corners().max(0)
        assert chair.cuboids == (1, 2) and abs(lo[1]) <= VOXEL and abs(hi[1] - 0.55) <= VOXEL
        assert lo[2] == 0.0 and abs(hi[2] - 0.9) <= VOXEL


@pytest.mark.parametrize(
    ("back", "pieces", "expected"),
    [
        (
            ((0, 0.55, 0.4), (1.4, 0.6, 0.9)),
            {1: ((0, 0, 0), (0.6, 0.5, 0.45)), 2: ((0.8, 0, 0), (1.4, 0.5, 0.45))},
            [1, 2],
        ),
        (
            ((0, 0.55, 0.4), (1.4, 0.6, 0.9)),
            {1: ((0, 0, 0), (0.6, 0.4, 0.45)), 2: ((0.8, 0, 0), (1.4, 0.4, 0.45))},
            [],
        ),
        (
            ((0, 0.55, 0.4), (2.6, 0.6, 0.9)),
            {1: ((0, 0, 0), (0.6, 0.5, 0.45)), 2: ((0.8, 0, 0), (1.4, 0.5, 0.45))},
            [],
        ),
        (
            ((0, 0.0, 0.4), (1.4, 0.6, 0.9)),
            {1: ((0, 0.6, 0), (0.6, 1.1, 0.45)), 2: ((0.8, 0.6, 0), (1.4, 1.1, 0.45))},
            [],
        ),
        (
            ((0, 0.55, 0.4), (1.4, 0.6, 0.9)),
            {1: ((0, 0, 0), (0.6, 0.5, 0.45)), 2: ((0.8, 0, 0), (1.6, 0.5, 0.45))},
            [],
        ),
        (
            ((0, 0.55, 0.5), (1.4, 0.6, 0.9)),
            {1: ((0, 0, 0), (0.6, 0.5, 0.45)), 2: ((0.8, 0, 0), (1.4, 0.5, 0.45))},
            [],
        ),
        (  # 9 cm away
            ((0, 0.59, 0.4), (1.4, 0.64, 0.9)),
            {1: ((0, 0, 0), (0.6, 0.5, 0.45)), 2: ((0.8, 0, 0), (1.4, 0.5, 0.45))},
            [],
        ),
        (  # a back 3.1 times as long as deep, with what grew onto it
            ((0, 0.5, 0.4), (1.4, 0.95, 0.9)),
            {1: ((0, 0, 0), (0.6, 0.5, 0.45)), 2: ((0.8, 0, 0), (1.4, 0.5, 0.45))},
            [1, 2],
        ),
        (
            ((0.55, 0, 0.4), (0.6, 1.4, 0.9)),
            {1: ((0, 0, 0), (0.5, 0.6, 0.45)), 2: ((0, 0.8, 0), (0.5, 1.4, 0.45))},
            [1, 2],
        ),
    ],
)
def test_pieces_beside_a_back(back, pieces, expected):
    """Seats within 7 cm of a back's long side, also of a back 3.1 times as long as deep; not 9 or 15 cm
    away, nor beside a 2.6 m run or a deep box, nor sticking out past its end, nor below its bottom; along x
    or y."""
    boxes = {0: _box(*back), **{g: _box(*b) for g, b in pieces.items()}}
    seeds = [4, 5, 5]
    assert pieces_inside(0, dict.fromkeys(boxes), seeds, {5}, lambda g, h: boxes[g], 0.9) == expected


def _box(lo, hi):
    return (list(lo), list(hi), float(np.prod(np.subtract(hi, lo))))


@pytest.mark.parametrize(
    ("pieces", "slabs", "expected"),
    [
        ({1: ((0, 0, 0), (0.6, 0.5, 0.4)), 2: ((0.75, 0, 0), (1.3, 0.5, 0.4))}, {5}, [1, 2]),  # two seats
        ({1: ((0, 0, 0), (0.6, 0.5, 0.4)), 2: ((0.65, 0, 0), (1.3, 0.5, 0.4))}, {5}, []),  # 5 cm apart
        ({1: ((0, 0, 0), (0.6, 0.5, 0.4)), 2: ((0.6, 0, 0), (1.3, 0.5, 0.4))}, {5}, []),  # touching
        ({1: ((0, 0, 0), (0.7, 0.5, 0.4)), 2: ((0.6, 0, 0), (1.3, 0.5, 0.4))}, {5}, []),  # overlapping
        ({1: ((0, 0, 0), (0.6, 0.5, 0.2)), 2: ((0, 0, 0.5), (0.6, 0.5, 0.9))}, {5}, []),  # stacked
        ({1: ((0, 0, 0), (0.6, 0.5, 0.4)), 2: ((0.75, 0, 0), (1.3, 0.5, 0.4))}, set(), []),  # no slab
        ({1: ((0, 0, 0), (0.6, 0.5, 0.4))}, {5}, []),  # one piece
        (
            {
                1: ((0, 0, 0), (0.4, 0.5, 0.4)),
                2: ((0.55, 0, 0), (1.3, 0.5, 0.4)),
                3: ((0.8, 0, 0), (1.3, 0.2, 0.4)),
            },
            {5},
            [],
        ),
        (
            {
                1: ((0, 0, 0), (0.4, 0.5, 0.4)),
                2: ((0.55, 0, 0), (0.85, 0.5, 0.4)),
                3: ((1.0, 0, 0), (1.3, 0.5, 0.4)),
            },
            {5},
            [1, 2, 3],
        ),
        ({1: ((0, 0, 0), (0.6, 0.5, 0.4)), 2: ((1.0, 0, 0), (1.6, 0.5, 0.4))}, {5}, []),  # one sticks out
    ],
)
def test_pieces_inside(pieces, slabs, expected):
    boxes = {0: _box((0, 0, 0), (1.3, 0.6, 0.9)), **{g: _box(*b) for g, b in pieces.items()}}
    groups = dict.fromkeys(boxes)
    seeds = [4, 5, 5, 5]
    assert pieces_inside(0, groups, seeds, slabs, lambda g, h: boxes[g], 0.9) == expected
    assert pieces_inside(0, groups, [-1, 5, 5, 5], slabs, lambda g, h: boxes[g], 0.9) == []  # a cluster


def test_nearest_piece_and_level_slabs():
    boxes = [_box((0, 0, 0), (0.6, 0.5, 0.4)), _box((0.7, 0, 0), (1.3, 0.5, 0.4))]
    xy = np.array([[0.3, 0.2], [0.64, 0.6], [0.66, -0.3], [1.0, 0.9], [2.0, 0.0]])
    np.testing.assert_array_equal(nearest_piece(xy, boxes), [0, 0, 1, 1, 1])
    seat = Cuboid([0, 0, 0.4], [0.3, 0.3, 0.02], np.eye(3))
    assert is_level_slab(seat, UP) and not is_level_slab(seat, np.array([1.0, 0.0, 0.0]))
    for degrees, level in ((18.0, True), (23.0, False)):
        c, s = np.cos(np.radians(degrees)), np.sin(np.radians(degrees))
        turned = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])
        assert is_level_slab(Cuboid([0, 0, 0.4], [0.3, 0.3, 0.02], turned), UP) == level
    assert not is_level_slab(Cuboid([0, 0, 0.4], [0.3, 0.3, 0.06], np.eye(3)), UP)  # 12 cm thick
    assert is_level_slab(Cuboid([0, 0, 0.4], [0.3, 0.3, 0.04], np.eye(3)), UP)  # 8 cm

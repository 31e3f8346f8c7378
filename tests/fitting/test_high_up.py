"""Boxes high in a room that are not furniture (:func:`cuboidcli.fitting.not_objects.high_up`): low-scored
ones more than a metre up, and ones no cuboid explains above a door's top (a rail, a light, a moulding); and
what hangs on a wall (:func:`cuboidcli.fitting.not_objects.hangs_on_wall`)."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting import not_objects
from cuboidcli.fitting.not_objects import (
    DOOR_TOP_M,
    HANG_BOTTOM_M,
    HANG_SCORE,
    HANG_THIN_M,
    HIGH_M,
    HIGH_SCORE,
    hangs_on_wall,
    high_up,
)
from cuboidcli.fitting.objects import group_objects
from tests.fitting.test_objects import VOXEL, _grid

UP = np.array([0.0, 0.0, 1.0])
FLOOR = Cuboid([2.0, 2.0, -0.02], [2.0, 2.0, 0.02], np.eye(3), kind="floor")  # top face at z = 0
#: A wall along y whose face is at x = 0 (the room is x > 0).
WALL = Cuboid([-0.05, 2.0, 1.3], [0.05, 2.0, 1.3], np.eye(3), kind="wall")


def _room(*parts, labels=None, cuboids=()):
    """Floor points (cuboid 0, every other voxel) and the parts, unlabelled unless ``labels`` gives one
    label per part; the cuboids are the floor, the wall and ``cuboids``."""
    floor = _grid((0.1, 0.1, 0.0), (3.9, 3.9, 0.0), 2 * VOXEL)
    labels = labels or [-1] * len(parts)
    pts = np.concatenate([floor, *parts])
    lab = np.concatenate(
        [np.zeros(len(floor))] + [np.full(len(p), k) for p, k in zip(parts, labels, strict=True)]
    )
    return pts, lab.astype(np.int32), [FLOOR, WALL, *cuboids]


def test_high_up_bounds():
    assert (HIGH_M, HIGH_SCORE, DOOR_TOP_M) == (1.0, 0.1, 2.0)
    # a low score more than a metre up, seeded or not
    assert high_up(1.0 + 1e-6, 0.099, True) and high_up(1.0 + 1e-6, 0.099, False)
    assert not high_up(1.0, 0.099, True) and not high_up(1.5, 0.1, True)
    # no cuboid and above a door's top, whatever the score
    assert high_up(2.0, 0.9, False) and not high_up(2.0 - 1e-6, 0.9, False)
    assert not high_up(2.4, 0.9, True)  # a cuboid holds it: a cupboard over a refrigerator
    assert not high_up(-0.5, 0.0, False)  # on the floor


def _rail(z):
    """A rail 1.2 m long along the wall, 10 cm from it: 7 x 35 x 4 points from height ``z``."""
    return _grid((0.1, 1.0, z), (0.31, 2.19, z + 0.105))


@pytest.mark.parametrize(
    ("z", "seeded", "kept"),
    [
        (2.3, False, False),  # above the doors, no cuboid: a curtain rail
        (2.0 + 0.5 * VOXEL, False, False),  # its box's bottom (half a voxel under its points) at 2 m
        (2.0 + 0.5 * VOXEL - 0.01, False, True),  # 1 cm lower
        (1.9, False, True),  # below a door's top
        (2.3, True, True),  # a cuboid explains it: a shelf
    ],
)
def test_a_rail_above_the_doors_that_no_cuboid_explains_is_left_out(z, seeded, kept):
    rail = _rail(z)
    shelf = Cuboid([0.2, 1.6, z + 0.05], [0.1, 0.6, 0.05], np.eye(3), kind="object")
    pts, lab, cuboids = _room(rail, labels=[2 if seeded else -1], cuboids=(shelf,) if seeded else ())
    out = group_objects(pts, lab, cuboids, UP, VOXEL)
    assert len(out) == int(kept)
    if kept:
        assert out[0].points == len(rail) and out[0].score > HIGH_SCORE
        assert out[0].cuboids == ((2,) if seeded else ())


def test_hangs_on_wall_bounds():
    assert (HANG_THIN_M, HANG_BOTTOM_M, HANG_SCORE) == (0.3, 0.3, 0.4)

    def slab(thick, off=0.0):  # a box against WALL (its face at x = 0), ``off`` clear of it, 1 m up
        return Cuboid([off + thick / 2, 2.0, 1.25], [thick / 2, 0.4, 0.25], np.eye(3), kind="object")

    assert hangs_on_wall(slab(0.3), [WALL], 1.0, 0.39)
    assert not hangs_on_wall(slab(0.31), [WALL], 1.0, 0.39)  # thicker: a cupboard
    assert hangs_on_wall(slab(0.2), [WALL], 0.3 + 1e-6, 0.39)
    assert not hangs_on_wall(slab(0.2), [WALL], 0.3, 0.39)  # low: it stands
    assert not hangs_on_wall(slab(0.2), [WALL], 1.0, 0.4)  # well filled: a cupboard seen whole
    assert not hangs_on_wall(slab(0.2, off=0.5), [WALL], 1.0, 0.1)  # clear of the wall
    assert not hangs_on_wall(slab(0.2), [], 1.0, 0.1)


def _shelf(z, depth=0.25, x0=0.08):
    """A board on the wall: a level layer of points ``depth`` deep from ``x0``, 0.8 m wide, at height z."""
    return _grid((x0, 1.6, z), (x0 + depth, 2.4, z))


def _back():
    """The front face and top edge of a sofa's back 0.25 m deep, from 0.4 to 0.85 m above the floor, 0.4 m of
    it seen."""
    return np.concatenate(
        [_grid((0.33, 1.8, 0.4), (0.33, 2.2, 0.85)), _grid((0.08, 1.8, 0.85), (0.3, 2.2, 0.85))]
    )


@pytest.mark.parametrize(
    ("points", "kept"),
    [
        (_shelf(1.2), False),  # a board hung on the wall, 1.2 m up
        (_shelf(0.6), False),  # lower down
        (_shelf(0.6, x0=0.6), True),  # clear of the wall: a table top
        (_shelf(1.2, depth=0.35), True),  # deeper than a thing hung on a wall
        (_grid((0.08, 1.6, 1.2), (0.33, 2.4, 1.8)), True),  # a cupboard, its box filled: it scores
        (_back(), True),  # low enough to stand on legs the scan missed: a sofa's back against the wall
    ],
)
def test_what_hangs_on_a_wall_is_left_out(points, kept, monkeypatch):
    pts, lab, cuboids = _room(points)
    out = group_objects(pts, lab, cuboids, UP, VOXEL)
    assert len(out) == int(kept)
    if not kept:  # this rule leaves it out, not the others (the wall's thin scraps, low scores high up)
        monkeypatch.setattr(not_objects, "HANG_SCORE", 0.0)
        out = group_objects(pts, lab, cuboids, UP, VOXEL)
        assert 0.0 < out[0].score < HANG_SCORE
    assert out[0].points == len(points)


def test_a_frame_on_a_wall_that_reaches_the_floor_stays():
    """The upper part of a window's frame hangs on the wall, its lower part stands on the floor: the lower
    joins the upper (:func:`~cuboidcli.fitting.nested.join_under`) before what hangs is left out, and the
    whole frame stays, from the floor to its top."""
    upper = np.concatenate(  # the front and back edges of a frame 0.25 m deep, from 1 m up to 1.8 m
        [_grid((x, 1.6, z), (x, 2.4, z)) for x in (0.08, 0.33) for z in (1.0, 1.8)]
        + [_grid((x, y, 1.0), (x, y, 1.8)) for x in (0.08, 0.33) for y in (1.6, 2.4)]
        + [_grid((0.08, y, z), (0.33, y, z)) for y in (1.6, 2.4) for z in (1.0, 1.8)]
    )
    post = _grid((0.08, 1.9, 0.14), (0.29, 2.1, 0.9))  # under it, 10 cm below: its own group
    alone = group_objects(*_room(upper), UP, VOXEL)
    assert alone == []  # the upper part alone hangs
    out = group_objects(*_room(upper, post), UP, VOXEL)
    assert len(out) == 1 and out[0].points == len(upper) + len(post)
    z = out[0].box.corners()[:, 2]
    assert z.min() == pytest.approx(0.0) and z.max() == pytest.approx(1.8 + VOXEL / 2)


def test_a_screen_on_a_desk_against_the_wall_stands():
    """A screen's front and foot, low-scored and flat against the wall, hang when nothing holds them; on a
    desk (:func:`~cuboidcli.fitting.nested.rests_on`) the screen stands and stays."""
    screen = np.concatenate(
        [_grid((0.3, 1.8, 0.85), (0.3, 2.2, 1.3)), _grid((0.1, 1.8, 0.85), (0.27, 2.2, 0.85))]
    )
    desk = _grid((0.08, 1.6, 0.75), (0.68, 2.4, 0.75))  # its top, 10 cm under the screen's foot
    assert group_objects(*_room(screen), UP, VOXEL) == []
    out = group_objects(*_room(screen, desk), UP, VOXEL)
    assert sorted(o.points for o in out) == sorted([len(screen), len(desk)])
    (held,) = [o for o in out if o.points == len(screen)]
    assert held.score < HANG_SCORE


def test_a_low_panel_on_a_wall_stands_wherever_the_floor_lies():
    """A panel against the wall from 0.2 to 1.3 m, low-scored and too tall to stand on unseen legs: its
    bottom, measured from its floor, is under 0.3 m: it does not hang, in a room on the ground or 1 m up."""
    panel = np.concatenate(
        [_grid((0.33, 1.9, 0.2), (0.33, 2.1, 1.3)), _grid((0.08, 1.9, 1.3), (0.3, 2.1, 1.3))]
    )
    for dz in (0.0, 1.0):
        pts, lab, cuboids = _room(panel)
        cuboids = [Cuboid(c.center + [0.0, 0.0, dz], c.half_size, c.rotation, kind=c.kind) for c in cuboids]
        (o,) = group_objects(pts + [0.0, 0.0, dz], lab, cuboids, UP, VOXEL)
        assert o.points == len(panel) and o.score < HANG_SCORE
        assert o.box.corners()[:, 2].min() == pytest.approx(dz + 0.2 - VOXEL / 2)

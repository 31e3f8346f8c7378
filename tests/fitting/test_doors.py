"""Doors that the fit gave a wall cuboid of their own (:mod:`cuboidcli.fitting.doors`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.doors import DOOR_COLOUR, DOOR_DEPTH_M, DOOR_MIN_POINTS, DOOR_WALL_GAP_M, door_walls
from cuboidcli.fitting.objects import group_objects
from cuboidcli.geometry.gravity import level_frame

UP = np.array([0.0, 0.0, 1.0])
VOXEL = 0.035
FLOOR = Cuboid([2.0, 2.0, -0.02], [2.0, 2.0, 0.02], np.eye(3), kind="floor")  # top face at z = 0
WALL = Cuboid([2.0, 4.0, 1.25], [2.0, 0.02, 1.25], np.eye(3), kind="wall")  # 4 m along x, its face at 3.98
WHITE, WOOD = [220.0, 220.0, 215.0], [120.0, 80.0, 40.0]


def _turned(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _room(slab: Cuboid, colour=WOOD, wall: Cuboid = WALL, n_door: int = 200):
    """Points, labels and colours: the wall's 60 white inliers (label 0), ``n_door`` inliers on the slab's
    face (label 1) of ``colour``, 100 floor points (label 2)."""
    wall_pts = np.array([[0.2 + 0.06 * i, 3.98, 1.8] for i in range(60)])
    u = np.linspace(-0.9, 0.9, 20)
    v = np.linspace(-0.9, 0.9, max(n_door // 20, 1))
    face = np.array([[a, -slab.half_size[1], b] for a in u for b in v])[:n_door]
    door_pts = face * np.r_[slab.half_size[0], 1.0, slab.half_size[2]] @ slab.rotation.T + slab.center
    floor_pts = np.array([[0.4 * i, 0.4 * j, 0.0] for i in range(10) for j in range(10)])
    pts = np.concatenate([wall_pts, door_pts, floor_pts])
    lab = np.concatenate([np.zeros(60), np.ones(len(door_pts)), np.full(100, 2)]).astype(np.int32)
    colors = np.concatenate(
        [np.tile(WHITE, (60, 1)), np.tile(colour, (len(door_pts), 1)), np.full((100, 3), 40.0)]
    )
    return pts, lab, [wall, _wall(slab), FLOOR], colors


def _wall(c: Cuboid) -> Cuboid:
    return Cuboid(c.center, c.half_size, c.rotation, kind="wall")


def _doors(pts, lab, cuboids, colors):
    R = level_frame(UP)
    return door_walls(pts @ R, lab, cuboids, R, np.zeros(len(pts)), colors)


DOOR = Cuboid([3.0, 3.99, 0.7], [0.45, 0.02, 0.7], np.eye(3))  # 0.9 m wide, from the floor to 1.4 m


def test_a_door_sized_slab_beside_a_wall_in_another_colour_is_a_door():
    (door,) = _doors(*_room(DOOR))
    index, box, local, lo, hi = door
    assert index == 1 and len(local) == 200
    corners = box.corners()
    # along the wall and up: the slab's extent from the floor; across: grown from 4 cm to 10 cm
    assert DOOR_DEPTH_M == 0.1
    np.testing.assert_allclose(corners.min(0), [2.55, 3.94, 0.0], atol=1e-9)
    np.testing.assert_allclose(corners.max(0), [3.45, 4.04, 1.4], atol=1e-9)
    np.testing.assert_allclose(hi - lo, box.half_size * 2, atol=1e-12)
    assert np.all(local >= lo - 1e-9) and np.all(local <= hi + 1e-9)


def test_a_door_stands_on_the_floor():
    """A slab whose cuboid stops 5 cm above the floor (the scan missed the gap under the door): its box
    goes down to the floor."""
    (door,) = _doors(*_room(Cuboid([3.0, 3.99, 0.75], [0.45, 0.02, 0.7], np.eye(3))))
    np.testing.assert_allclose(door[1].corners().min(0)[2], 0.0, atol=1e-9)
    np.testing.assert_allclose(door[1].corners().max(0)[2], 1.45, atol=1e-9)
    assert door[3][2] == 0.0


def test_a_door_keeps_a_depth_over_10_cm():
    deep = Cuboid(DOOR.center, [0.45, 0.08, 0.7], np.eye(3))
    (door,) = _doors(*_room(deep))
    np.testing.assert_allclose(door[1].half_size * 2, [0.9, 0.16, 1.4], atol=1e-9)


def test_the_colour_must_differ_by_30():
    grey = np.array(WHITE) - [DOOR_COLOUR / math.sqrt(3)] * 3
    assert DOOR_COLOUR == 30.0
    assert len(_doors(*_room(DOOR, colour=list(grey - 0.01)))) == 1
    assert len(_doors(*_room(DOOR, colour=list(grey + 0.01)))) == 0
    assert len(_doors(*_room(DOOR, colour=WHITE))) == 0
    pts, lab, cuboids, _ = _room(DOOR)
    assert _doors(pts, lab, cuboids, None) == []


@pytest.mark.parametrize(
    ("half", "z", "found"),
    [
        ((0.3005, 0.02, 0.7), 0.7, True),  # 0.601 m wide (0.6 m: the bound)
        ((0.2995, 0.02, 0.7), 0.7, False),
        ((0.5995, 0.02, 0.7), 0.7, True),  # 1.199 m (1.2 m)
        ((0.6005, 0.02, 0.7), 0.7, False),
        ((0.45, 0.02, 0.6005), 0.6005, True),  # 1.201 m tall (1.2 m)
        ((0.45, 0.02, 0.5995), 0.5995, False),
        ((0.45, 0.02, 0.7), 0.799, True),  # 9.9 cm up (10 cm)
        ((0.45, 0.02, 0.7), 0.801, False),
    ],
)
def test_only_a_slab_of_a_doors_size_on_the_floor(half, z, found):
    assert len(_doors(*_room(Cuboid([3.0, 3.99, z], list(half), np.eye(3))))) == int(found)


def test_the_larger_wall_must_be_beside_it():
    assert DOOR_WALL_GAP_M == 0.3  # from the wall's centre (y = 4) to the slab's
    near = Cuboid([3.0, 3.72, 0.7], [0.45, 0.02, 0.7], np.eye(3))
    far = Cuboid([3.0, 3.68, 0.7], [0.45, 0.02, 0.7], np.eye(3))
    assert len(_doors(*_room(near))) == 1 and len(_doors(*_room(far))) == 0
    # past the wall's end (x = 4) by less and by more than its own width (0.9 m)
    assert len(_doors(*_room(Cuboid([4.85, 3.99, 0.7], [0.45, 0.02, 0.7], np.eye(3))))) == 1
    assert len(_doors(*_room(Cuboid([4.95, 3.99, 0.7], [0.45, 0.02, 0.7], np.eye(3))))) == 0
    # turned 8 and 12 degrees about up from the wall (10 degrees bound)
    assert len(_doors(*_room(Cuboid(DOOR.center, DOOR.half_size, _turned(8))))) == 1
    assert len(_doors(*_room(Cuboid(DOOR.center, DOOR.half_size, _turned(12))))) == 0
    # the wall beside it must be the larger
    small = Cuboid(WALL.center, [0.4, 0.02, 0.6], np.eye(3), kind="wall")
    assert len(_doors(*_room(DOOR, wall=small))) == 0
    long_low = Cuboid([3.0, 4.0, 1.8], [1.0, 0.02, 0.3], np.eye(3), kind="wall")  # 0.6 m^2 against 1.26
    assert len(_doors(*_room(DOOR, wall=long_low))) == 0
    level = Cuboid([2.0, 4.0, 1.25], [2.0, 1.25, 0.02], np.eye(3), kind="wall")  # large, but not upright
    assert len(_doors(*_room(DOOR, wall=level))) == 0


def test_the_nearest_larger_wall_gives_the_colour():
    """Two larger walls beside the door: the white one in its plane and a wooden one 25 cm behind it; the
    door is told from the nearer."""
    pts, lab, cuboids, colors = _room(DOOR)
    behind = Cuboid([2.0, 3.74, 1.25], [2.0, 0.02, 1.25], np.eye(3), kind="wall")
    extra = np.array([[0.2 + 0.06 * i, 3.76, 2.0] for i in range(60)])
    pts2 = np.concatenate([pts, extra])
    lab2 = np.concatenate([lab, np.full(60, 3)]).astype(np.int32)
    colors2 = np.concatenate([colors, np.tile(WOOD, (60, 1))])
    assert len(_doors(pts2, lab2, [*cuboids, behind], colors2)) == 1
    wood_near = colors2.copy()
    wood_near[lab2 == 0], wood_near[lab2 == 3] = WOOD, WHITE
    assert len(_doors(pts2, lab2, [*cuboids, behind], wood_near)) == 0


def _about_x(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def test_a_door_needs_its_inliers_and_an_upright_slab():
    assert len(_doors(*_room(DOOR, n_door=DOOR_MIN_POINTS))) == 1
    assert len(_doors(*_room(DOOR, n_door=DOOR_MIN_POINTS - 1))) == 0
    tipped = Cuboid([3.0, 3.0, 0.7], [0.45, 0.7, 0.02], np.eye(3))  # level: its thin axis up
    assert len(_doors(*_room(tipped))) == 0
    # its normal 10 and 13 degrees out of level (sin 11.5 degrees = 0.2)
    assert len(_doors(*_room(Cuboid(DOOR.center, DOOR.half_size, _about_x(10))))) == 1
    assert len(_doors(*_room(Cuboid(DOOR.center, DOOR.half_size, _about_x(13))))) == 0
    # the wall leaning with it: parallel, but both 13 degrees out of upright
    leaning = Cuboid(WALL.center, WALL.half_size, _about_x(13), kind="wall")
    assert len(_doors(*_room(Cuboid(DOOR.center, DOOR.half_size, _about_x(13)), wall=leaning))) == 0
    assert len(_doors(*_room(Cuboid(DOOR.center, DOOR.half_size, _about_x(10)), wall=leaning))) == 0


def test_a_room_with_another_up_and_a_higher_floor():
    """The same room with y up instead of z (turned -90 degrees about x) and its floor 1 m higher: the same
    door, its box turned alike, from the floor at 1 m."""
    pts, lab, cuboids, colors = _room(DOOR)
    T = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # (x, y, z) -> (x, z, -y)
    up = T @ UP
    lift = up * 1.0
    moved = [Cuboid(T @ c.center + lift, c.half_size, T @ c.rotation, kind=c.kind) for c in cuboids]
    R = level_frame(up)
    level = (pts @ T.T + lift) @ R
    (door,) = door_walls(level, lab, moved, R, np.full(len(pts), 1.0), colors)  # the floor 1 m up
    (plain,) = _doors(pts, lab, cuboids, colors)
    np.testing.assert_allclose(door[1].center, T @ plain[1].center + lift, atol=1e-9)
    np.testing.assert_allclose(door[1].half_size, plain[1].half_size, atol=1e-9)
    heights = door[1].corners() @ up
    np.testing.assert_allclose([heights.min(), heights.max()], [1.0, 2.4], atol=1e-9)
    short = Cuboid([3.0, 3.99, 0.5905], [0.45, 0.02, 0.5905], np.eye(3))  # 1.181 m tall: no door
    pts, lab, cuboids, colors = _room(short)
    moved = [Cuboid(T @ c.center + lift, c.half_size, T @ c.rotation, kind=c.kind) for c in cuboids]
    assert door_walls((pts @ T.T + lift) @ R, lab, moved, R, np.full(len(pts), 1.0), colors) == []


def test_a_turned_room_gives_the_same_door():
    """The room and its wall turned 30 degrees about up: the same door box, turned."""
    T = _turned(30)
    pts, lab, cuboids, colors = _room(DOOR)
    moved = [Cuboid(T @ c.center, c.half_size, T @ c.rotation, kind=c.kind) for c in cuboids]
    (door,) = _doors(pts @ T.T, lab, moved, colors)
    (plain,) = _doors(pts, lab, cuboids, colors)
    np.testing.assert_allclose(door[1].center, T @ plain[1].center, atol=1e-9)
    np.testing.assert_allclose(door[1].half_size, plain[1].half_size, atol=1e-9)


def test_the_room_grouping_lists_the_door_with_its_cuboid():
    pts, lab, cuboids, colors = _room(DOOR)
    objects = group_objects(pts, lab, cuboids, UP, VOXEL, colors)
    (door,) = [o for o in objects if o.cuboids == (1,)]
    assert door.points == 200 and 0.0 < door.score <= 1.0 and door.kind == "door"
    assert not [o for o in group_objects(pts, lab, cuboids, UP, VOXEL) if o.cuboids == (1,)]


def test_the_door_comes_with_the_rooms_other_objects_largest_first():
    """A crate of 343 unexplained points in the middle of the room: two objects, the crate first."""
    pts, lab, cuboids, colors = _room(DOOR)
    g = np.arange(7) * VOXEL
    crate = np.stack(np.meshgrid(g + 1.5, g + 1.5, g + 0.14, indexing="ij"), -1).reshape(-1, 3)
    pts = np.concatenate([pts, crate])
    lab = np.concatenate([lab, np.full(len(crate), -1)]).astype(np.int32)
    colors = np.concatenate([colors, np.tile(WOOD, (len(crate), 1))])
    objects = group_objects(pts, lab, cuboids, UP, VOXEL, colors)
    assert [(o.cuboids, o.points) for o in objects] == [((), 343), ((1,), 200)]

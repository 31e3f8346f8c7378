"""Doors in their wall's plane, told from the wall by their colour (:mod:`cuboidcli.fitting.door_leaves`)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.door_leaves import (
    LEAF_CONTRAST,
    LEAF_DEPTH_M,
    LEAF_MIN_POINTS,
    LEAF_SAME_M,
    door_leaves,
)
from cuboidcli.fitting.objects import group_objects
from cuboidcli.geometry.gravity import level_frame

UP = np.array([0.0, 0.0, 1.0])
VOXEL = 0.035
STEP = 0.025  # the wall's points, on a grid
WHITE, WOOD = np.array([220.0, 220.0, 215.0]), np.array([120.0, 80.0, 40.0])
# a wall 4 m along x with its face at y = 3.98, its thickness beyond
WALL = Cuboid([2.0, 4.0, 1.25], [2.0, 0.02, 1.25], np.eye(3), kind="wall")
FLOOR = Cuboid([2.0, 2.0, -0.02], [2.0, 2.0, 0.02], np.eye(3), kind="floor")


def wall_points(door=(1.5, 2.4), top=2.05, colour=WOOD, height=2.5, length=(0.0, 4.0), gap=None, bottom=0.0):
    """The wall's face on a grid, white, with a door from ``door[0]`` to ``door[1]`` along x and from
    ``bottom`` to ``top`` in ``colour``; no points between ``gap[0]`` and ``gap[1]`` along x."""
    x, z = np.meshgrid(
        np.arange(length[0], length[1], STEP) + STEP / 2, np.arange(0.0, height, STEP) + STEP / 2
    )
    x, z = x.ravel(), z.ravel()
    if gap is not None:
        x, z = x[(x < gap[0]) | (x > gap[1])], z[(x < gap[0]) | (x > gap[1])]
    pts = np.c_[x, np.full(len(x), 3.98), z]
    on_door = (x >= door[0]) & (x <= door[1]) & (z <= top) & (z >= bottom)
    colors = np.where(on_door[:, None], colour, WHITE)
    return pts, colors


def leaves(pts, colors, cuboids=(WALL,), labels=None, known=(), up=UP, under=0.0):
    R = level_frame(up)
    labels = np.zeros(len(pts), dtype=np.int64) if labels is None else labels
    return door_leaves(pts @ R, labels, list(cuboids), R, np.full(len(pts), under), colors, list(known))


def extent(box: Cuboid) -> tuple[np.ndarray, np.ndarray]:
    corners = box.corners()
    return corners.min(0), corners.max(0)


def test_a_wooden_door_in_a_white_wall_is_found():
    pts, colors = wall_points()
    (door,) = leaves(pts, colors)
    index, box, local, lo, hi = door
    assert index == 0
    low, high = extent(box)
    assert low[0] == pytest.approx(1.5, abs=0.06) and high[0] == pytest.approx(2.4, abs=0.06)
    assert low[2] == pytest.approx(0.0, abs=1e-9)
    assert high[2] == pytest.approx(2.05, abs=0.08)  # the top of the door's colour (a percentile)
    assert high[1] - low[1] == pytest.approx(LEAF_DEPTH_M)
    assert (low[1] + high[1]) / 2 == pytest.approx(3.98, abs=1e-6)  # centred on the wall's face
    assert box.kind == "object"
    assert len(local) > LEAF_MIN_POINTS
    assert np.all((local >= lo - 1e-9) & (local <= hi + 1e-9))


def test_what_the_box_holds_is_the_runs_points_in_its_frame():
    pts, colors = wall_points()
    (_, box, local, lo, hi) = leaves(pts, colors)[0]
    world = (local - (lo + hi) / 2) @ box.rotation.T + box.center
    inside = np.all(np.abs((world - box.center) @ box.rotation) <= box.half_size + 1e-9, axis=1)
    assert inside.all()
    assert np.isin(np.round(world, 6), np.round(pts, 6)).all()


def test_the_door_needs_its_colour_to_differ_from_the_wall():
    pts, colors = wall_points()
    grey = WHITE - np.array([LEAF_CONTRAST + 1.0, 0.0, 0.0])
    assert len(leaves(pts, np.where((colors == WOOD).all(1)[:, None], grey, colors))) == 1
    close = WHITE - np.array([LEAF_CONTRAST - 1.0, 0.0, 0.0])
    assert leaves(pts, np.where((colors == WOOD).all(1)[:, None], close, colors)) == []


def test_no_colours_no_doors():
    pts, _ = wall_points()
    assert leaves(pts, None) == []


@pytest.mark.parametrize(
    ("door", "found"), [((1.5, 2.15), True), ((1.5, 2.0), False), ((1.0, 2.5), True), ((1.0, 2.75), False)]
)
def test_a_door_is_a_door_wide(door, found):
    pts, colors = wall_points(door=door)
    assert bool(leaves(pts, colors)) == found


@pytest.mark.parametrize(
    ("top", "found"), [(2.05, True), (2.2, True), (2.5, False), (1.6, True), (1.4, False)]
)
def test_the_colour_stops_at_a_doors_top(top, found):
    pts, colors = wall_points(top=top)  # 2.5: a stretch of the wall in another paint, floor to ceiling
    assert bool(leaves(pts, colors)) == found


@pytest.mark.parametrize(("bottom", "found"), [(0.0, True), (0.3, True), (0.5, False)])
def test_the_colour_comes_down_to_the_floor(bottom, found):
    pts, colors = wall_points(bottom=bottom)  # from 0.5 m: a screen or a panel on the wall, not a door
    assert bool(leaves(pts, colors)) == found


def test_the_wall_must_be_seen_on_both_sides():
    pts, colors = wall_points(door=(0.0, 0.9))  # in a corner: no wall on its left
    assert leaves(pts, colors) == []
    pts, colors = wall_points(door=(0.45, 1.35))  # 45 cm of wall on its left
    assert len(leaves(pts, colors)) == 1
    pts, colors = wall_points(door=(1.5, 2.4), gap=(2.45, 2.9))  # the wall beside it unseen
    assert leaves(pts, colors) == []


def test_a_column_without_points_does_not_split_the_door():
    pts, colors = wall_points(gap=(1.88, 1.97))  # a handle's shadow: one or two columns without points
    (door,) = leaves(pts, colors)
    low, high = extent(door[1])
    assert low[0] == pytest.approx(1.5, abs=0.06) and high[0] == pytest.approx(2.4, abs=0.06)
    pts, colors = wall_points(gap=(1.85, 2.05))  # 20 cm unseen: two pieces, each too narrow for a door
    assert leaves(pts, colors) == []


def test_the_sides_colours_may_differ_from_each_other():
    pts, colors = wall_points()
    right = pts[:, 0] > 2.45
    colors[right] = [230.0, 200.0, 150.0]  # a second paint beside the door, still far from the wood
    assert len(leaves(pts, colors)) == 1


def test_a_door_seen_in_two_walls_planes_is_kept_once_and_not_twice_with_a_known_door():
    pts, colors = wall_points()
    twin = Cuboid(WALL.center + [0.0, 0.01, 0.0], WALL.half_size, WALL.rotation, kind="wall")
    labels = (np.arange(len(pts)) % 2).astype(np.int64)
    (door,) = leaves(pts, colors, cuboids=(WALL, twin), labels=labels)
    known = Cuboid(door[1].center + [LEAF_SAME_M - 0.01, 0.0, 0.0], [0.4, 0.1, 1.0], np.eye(3))
    assert leaves(pts, colors, known=(known,)) == []
    far = Cuboid(door[1].center + [LEAF_SAME_M + 0.01, 0.0, 0.0], [0.4, 0.1, 1.0], np.eye(3))
    assert len(leaves(pts, colors, known=(far,))) == 1


def test_only_an_upright_wall_with_its_inliers_is_looked_at():
    pts, colors = wall_points()
    assert leaves(pts, colors, labels=np.full(len(pts), -1)) == []
    tilt = math.radians(15.0)  # its normal 15 degrees off level
    T = np.array(
        [[1.0, 0.0, 0.0], [0.0, math.cos(tilt), -math.sin(tilt)], [0.0, math.sin(tilt), math.cos(tilt)]]
    )
    leaning = Cuboid(WALL.center, WALL.half_size, T, kind="wall")
    assert leaves(pts, colors, cuboids=(leaning,)) == []
    assert leaves(pts, colors, cuboids=(Cuboid(WALL.center, WALL.half_size, np.eye(3), kind="object"),)) == []


def test_a_room_on_its_side_with_a_higher_floor():
    pts, colors = wall_points()
    T = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # z up turned to x up
    lift = np.array([1.0, 0.0, 0.0])
    moved = Cuboid(T @ WALL.center + lift, WALL.half_size, T @ WALL.rotation, kind="wall")
    (door,) = leaves(pts @ T.T + lift, colors, cuboids=(moved,), up=np.array([1.0, 0.0, 0.0]), under=1.0)
    low, high = extent(door[1])
    assert low[0] == pytest.approx(1.0, abs=1e-9) and high[0] == pytest.approx(3.05, abs=0.08)
    assert (low[2], high[2]) == (pytest.approx(-2.4, abs=0.06), pytest.approx(-1.5, abs=0.06))


def test_the_rooms_grouping_lists_the_door_with_its_wall():
    pts, colors = wall_points()
    floor = np.array([[0.1 * i, 0.1 * j, 0.0] for i in range(40) for j in range(39)])
    labels = np.r_[np.zeros(len(pts)), np.ones(len(floor))].astype(np.int64)
    all_colors = np.r_[colors, np.full((len(floor), 3), 90.0)]
    objects = group_objects(np.r_[pts, floor], labels, [WALL, FLOOR], UP, VOXEL, all_colors)
    (door,) = objects
    assert door.cuboids == (0,) and 0.0 < door.score <= 1.0 and door.points > LEAF_MIN_POINTS
    assert door.kind == "door" and door.to_dict(0)["kind"] == "door"
    low, high = extent(door.box)
    assert high[0] - low[0] == pytest.approx(0.9, abs=0.11)
    assert group_objects(np.r_[pts, floor], labels, [WALL, FLOOR], UP, VOXEL) == []


@pytest.mark.parametrize(("offset", "found"), [(0.05, True), (-0.05, True), (0.07, False), (-0.07, False)])
def test_the_doors_points_lie_within_6_cm_of_the_walls_face(offset, found):
    pts, colors = wall_points()
    on_door = (colors == WOOD).all(axis=1)
    pts[on_door, 1] += offset  # a leaf standing proud of its wall, or set back into its opening
    assert bool(leaves(pts, colors)) == found


@pytest.mark.parametrize(("missing", "found"), [((1.1, 1.7), True), ((0.7, 1.7), False)])
def test_a_doors_columns_must_be_40_percent_filled(missing, found):
    pts, colors = wall_points()
    keep = ~((pts[:, 0] > 1.45) & (pts[:, 0] < 2.45) & (pts[:, 2] > missing[0]) & (pts[:, 2] < missing[1]))
    # 0.6 / 1.5 or 1.0 / 1.5 of the columns' rows between 0.2 and 1.7 m left unseen
    assert bool(leaves(pts[keep], colors[keep])) == found


@pytest.mark.parametrize(("distance", "found"), [(40.0, False), (50.0, True)])
def test_the_door_differs_from_the_wall_by_45(distance, found):
    pts, colors = wall_points()
    colors[(colors == WOOD).all(axis=1)] = WHITE - [distance, 0.0, 0.0]
    assert bool(leaves(pts, colors)) == found


def test_the_box_is_20_cm_deep_and_a_door_within_30_cm_is_known():
    pts, colors = wall_points()
    (door,) = leaves(pts, colors)
    low, high = extent(door[1])
    assert high[1] - low[1] == pytest.approx(0.2)
    for shift, found in ((0.25, False), (0.35, True)):
        known = Cuboid(door[1].center + [shift, 0.0, 0.0], [0.4, 0.1, 1.0], np.eye(3))
        assert bool(leaves(pts, colors, known=(known,))) == found


def test_points_below_the_floor_or_above_2_4_m_are_not_looked_at():
    pts, colors = wall_points(height=3.5)  # the wall goes on to 3.5 m, white
    below = pts[pts[:, 2] < 0.6] - [0.0, 0.0, 0.6]  # a reflection under the floor, in the door's colour
    wood = np.tile(WOOD, (len(below), 1))
    (door,) = leaves(np.r_[pts, below], np.r_[colors, wood])
    low, high = extent(door[1])
    assert low[2] == pytest.approx(0.0) and high[2] == pytest.approx(2.05, abs=0.08)


@pytest.mark.parametrize(("end", "found"), [(2.45, True), (2.1, False)])
def test_the_band_reaches_30_cm_beyond_the_walls_inliers(end, found):
    pts, colors = wall_points()
    labels = np.where(pts[:, 0] <= end, 0, -1)  # the wall's cuboid took its points only up to ``end``
    # up to 2.45 m: the band reaches 2.75 m, past the door's right side (2.5-2.8 m); up to 2.1 m it stops
    # at 2.4 m, and the wall beside the door is never seen
    assert bool(leaves(pts, colors, labels=labels)) == found

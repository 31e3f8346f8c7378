"""The room's shell in numbers (fitting/shell.py): slabs and point sets built so that the share of points
beyond each slab is known exactly, checked against the rules of :func:`beyond_share`, :func:`is_room_slab`
and :func:`cuboid_kind` just inside and just outside each of their thresholds (15 cm past the far face, 5 %
of the points, a quarter of a room behind an upright slab, upright beyond 60 degrees from vertical, level or
upright within 20 degrees)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.shell import beyond_share, cuboid_kind, is_room_slab

EYE = np.eye(3)


def _rx(deg: float) -> np.ndarray:
    t = np.deg2rad(deg)
    return np.array([[1.0, 0.0, 0.0], [0.0, np.cos(t), -np.sin(t)], [0.0, np.sin(t), np.cos(t)]])


def _at(z: float, n: int, x: float = 0.0) -> np.ndarray:
    return np.tile([x, 0.0, z], (n, 1))


def test_a_point_counts_beyond_a_slab_15_cm_past_its_far_face_seen_from_the_camera():
    # a slab 20 cm thick at z = 2 (far face z = 2.1): 10 points on it, 4 a tenth past the far face, 6 a fifth
    pts = np.concatenate([_at(2.0, 10), _at(2.2, 4), _at(2.3, 6)])
    c, a = np.array([0.0, 0.0, 2.0]), np.array([1.0, 1.0, 0.1])
    assert beyond_share(pts, c, a, EYE, 2) == pytest.approx(6 / 20)
    # the normal's sign does not matter: the far face is the one away from the camera
    flipped = np.diag([1.0, -1.0, -1.0])
    assert beyond_share(pts, c, a, flipped, 2) == pytest.approx(6 / 20)
    # points in front of it (between the camera and the slab) are never beyond it
    near = np.concatenate([pts, _at(0.5, 20)])
    assert beyond_share(near, c, a, EYE, 2) == pytest.approx(6 / 40)
    # seen from behind (a viewpoint at z = 5), the points in front are the ones beyond
    assert beyond_share(near, c, a, EYE, 2, viewpoint=np.array([0.0, 0.0, 5.0])) == pytest.approx(20 / 40)
    # an empty frame has nothing beyond anything
    assert beyond_share(np.zeros((0, 3)), c, a, EYE, 2) == 0.0


def test_behind_an_upright_slab_only_its_own_rectangle_grown_by_15_cm_counts():
    up = np.array([0.0, -1.0, 0.0])
    c, a = np.array([0.0, 0.0, 3.0]), np.array([1.0, 1.0, 0.05])  # a wall 2 x 2 m at z = 3
    xs, ys = np.meshgrid(np.linspace(-0.9, 0.9, 8), np.linspace(-0.9, 0.9, 5))
    wall = np.c_[xs.ravel(), ys.ravel(), np.full(40, 3.0)]
    # 1 m behind it: 2 points straight behind, 2 at x = 1.1 (within the grown rectangle), 2 at +-1.3
    behind = np.concatenate([_at(4.0, 2), _at(4.0, 2, 1.1), _at(4.0, 1, 1.3), _at(4.0, 1, -1.3)])
    pts = np.concatenate([wall, behind])
    eye_pt = np.zeros(3)
    assert beyond_share(pts, c, a, EYE, 2, eye_pt, up) == pytest.approx(4 / 46)
    # without a viewpoint (a frame's camera) or without up, every point beyond the plane counts
    assert beyond_share(pts, c, a, EYE, 2) == pytest.approx(6 / 46)
    assert beyond_share(pts, c, a, EYE, 2, eye_pt) == pytest.approx(6 / 46)
    assert beyond_share(pts, c, a, EYE, 2, None, up) == pytest.approx(6 / 46)
    # a wall turned 90 degrees (its thickness along x) has the same rule about its own axes
    turned = np.array([[0.0, 0.0, 1.0], [0.0, 1.0, 0.0], [-1.0, 0.0, 0.0]])  # columns: -z, y, x
    # and moved 50 cm right and 30 cm down: its rectangle moves with it
    shift = np.array([0.5, 0.3, 0.0])
    assert beyond_share(pts + shift, c + shift, a, EYE, 2, eye_pt, up) == pytest.approx(4 / 46)
    got = beyond_share(pts[:, [2, 1, 0]], c[[2, 1, 0]], a[[2, 1, 0]], EYE, 0, eye_pt, up)
    assert got == pytest.approx(4 / 46)
    assert beyond_share(pts, c, a[[2, 1, 0]], turned, 0, eye_pt, up) == pytest.approx(4 / 46)


def test_a_quarter_of_the_room_behind_an_upright_slab_makes_it_something_standing_in_the_room():
    up = np.array([0.0, -1.0, 0.0])
    c, a = np.array([0.0, 0.0, 3.0]), np.array([1.0, 1.0, 0.05])
    eye_pt = np.zeros(3)
    # 10 of 40 points behind the slab's plane but off its rectangle: exactly a quarter is not "more"
    quarter = np.concatenate([_at(3.0, 30), _at(4.0, 10, 3.0)])
    assert beyond_share(quarter, c, a, EYE, 2, eye_pt, up) == 0.0
    # 12 of 40 is: the slab gets the whole share
    more = np.concatenate([_at(3.0, 28), _at(4.0, 12, 3.0)])
    assert beyond_share(more, c, a, EYE, 2, eye_pt, up) == pytest.approx(12 / 40)


def test_a_slab_whose_normal_is_50_degrees_from_up_is_not_upright():
    """Upright means a normal more than 60 degrees from vertical: a slab whose normal is 50 degrees from up
    counts every point beyond its plane, an upright one (normal 65 degrees from up) only its rectangle's."""
    up = np.array([0.0, -1.0, 0.0])
    c, a = np.array([0.0, 0.0, 3.0]), np.array([0.5, 0.5, 0.02])
    for phi, expected in ((40.0, 2 / 22), (25.0, 0.0)):
        R = _rx(phi)  # the normal (column 2) (0, -sin phi, cos phi): 90 - phi degrees from up
        assert abs(R[:, 2] @ up) == pytest.approx(np.sin(np.deg2rad(phi)))
        on = c + np.c_[np.linspace(-0.4, 0.4, 20), np.zeros(20), np.zeros(20)] @ R.T
        far_off = c + np.array([[3.0, 0.0, 1.0], [-3.0, 0.0, 1.0]]) @ R.T  # 1 m beyond, off the rectangle
        pts = np.concatenate([on, far_off])
        assert beyond_share(pts, c, a, R, 2, np.zeros(3), up) == pytest.approx(expected)


def test_a_room_slab_has_at_most_5_percent_of_the_points_beyond_it():
    c, a = np.array([0.0, 0.0, 2.0]), np.array([1.0, 1.0, 0.02])
    one_in_20 = np.concatenate([_at(2.0, 19), _at(3.0, 1)])
    assert is_room_slab(one_in_20, c, a, EYE)  # exactly 5 %
    three_in_50 = np.concatenate([_at(2.0, 47), _at(3.0, 3)])
    assert not is_room_slab(three_in_50, c, a, EYE)  # 6 %
    # a slab whose thickness is its first axis, and a box that is no slab with nothing beyond it
    assert is_room_slab(one_in_20[:, [2, 1, 0]], c[[2, 1, 0]], a[[2, 1, 0]], EYE)
    assert not is_room_slab(_at(2.0, 20), c, np.array([1.0, 1.0, 0.5]), EYE)
    assert is_room_slab(np.zeros((0, 3)), c, a, EYE)


def _column(n: int = 400) -> np.ndarray:
    """Points of a room 1 x 1 m wide (x, y in [-0.5, 0.5]) from z = 5 to 7.5 (z up), far from the origin."""
    rng = np.random.default_rng(0)
    return rng.uniform([-0.5, -0.5, 5.0], [0.5, 0.5, 7.5], (n, 3))


DOWN = np.array([0.0, 0.0, -1.0])
VIEW = np.array([0.0, 0.0, 6.5])


@pytest.mark.parametrize("tilt, kind", [(0.0, "floor"), (15.0, "floor"), (25.0, "object")])
def test_a_level_slab_below_the_viewpoint_is_a_floor_within_20_degrees(tilt, kind):
    pts = _column()
    floor = Cuboid([0.0, 0.0, 4.8], [0.3, 0.3, 0.02], _rx(tilt))
    assert is_room_slab(pts, floor.center, floor.half_size, floor.rotation, VIEW, -DOWN)
    assert cuboid_kind(pts, floor, DOWN, VIEW) == kind
    # the same slab is under the room's viewpoint but above the origin: without the viewpoint it would be
    # a ceiling (and the points are then beyond it)
    if tilt == 0.0:
        ceiling = Cuboid([0.0, 0.0, 7.7], [0.3, 0.3, 0.02], EYE)
        assert cuboid_kind(pts, ceiling, DOWN, VIEW) == "ceiling"
        low = Cuboid([0.0, 0.0, -0.2], [0.3, 0.3, 0.02], EYE)
        assert cuboid_kind(pts, low, DOWN) == "floor"
        high = Cuboid([0.0, 0.0, 0.2], [0.3, 0.3, 0.02], EYE)
        assert cuboid_kind(-pts, high, DOWN) == "ceiling"


@pytest.mark.parametrize("tilt, kind", [(0.0, "wall"), (15.0, "wall"), (25.0, "object")])
def test_an_upright_slab_is_a_wall_within_20_degrees_of_vertical(tilt, kind):
    pts = _column()
    # a wall at x = 0.6 facing the room (thickness along x), leaning by ``tilt`` about y
    t = np.deg2rad(tilt)
    R = np.array([[np.cos(t), 0.0, np.sin(t)], [0.0, 1.0, 0.0], [-np.sin(t), 0.0, np.cos(t)]])
    wall = Cuboid([0.7, 0.0, 6.25], [0.02, 0.5, 0.3], R)
    assert is_room_slab(pts, wall.center, wall.half_size, wall.rotation, VIEW, -DOWN)
    assert cuboid_kind(pts, wall, DOWN, VIEW) == kind


def test_a_box_with_the_room_beyond_it_is_an_object_whatever_its_direction():
    pts = _column()
    table = Cuboid([0.0, 0.0, 5.7], [0.3, 0.3, 0.02], EYE)  # a level slab with 0.7 m of room under it
    assert cuboid_kind(pts, table, DOWN, VIEW) == "object"


def test_the_thresholds_themselves_are_inside():
    """Exactly 15 cm past the far face is not beyond; the grown rectangle's edge is in it; a normal exactly
    60 degrees from up is not upright."""
    c, a = np.array([0.0, 0.0, 2.0]), np.array([1.0, 1.0, 0.1])
    assert beyond_share(np.concatenate([_at(2.0, 3), _at(2.25, 1)]), c, a, EYE, 2) == 0.0
    up = np.array([0.0, -1.0, 0.0])
    wall = np.concatenate([_at(2.0, 3), _at(3.0, 1, 1.15)])  # behind it, at x = 1 m + 15 cm
    assert beyond_share(wall, c, a, EYE, 2, np.zeros(3), up) == pytest.approx(1 / 4)
    # a normal (0, -0.5, sqrt 0.75): 60 degrees from up, every point beyond its plane counts
    s = np.sqrt(0.75)
    R = np.array([[1.0, 0.0, 0.0], [0.0, s, -0.5], [0.0, 0.5, s]])
    assert float(R[:, 2] @ up) == 0.5
    far_off = c + np.array([[3.0, 0.0, 1.0], [-3.0, 0.0, 1.0]]) @ R.T
    pts = np.concatenate([np.tile(c, (8, 1)), far_off])
    assert beyond_share(pts, c, a, R, 2, np.zeros(3), up) == pytest.approx(2 / 10)


def test_a_single_point_and_a_slab_half_a_metre_away():
    c, a = np.array([0.0, 0.0, 0.5]), np.array([1.0, 1.0, 0.05])
    assert beyond_share(_at(1.0, 1), c, a, EYE, 2) == 1.0
    assert beyond_share(_at(0.0, 1) + [0.0, 0.0, 0.1], c, a, EYE, 2) == 0.0  # in front of it
    # the far face is the one away from the camera even 50 cm from it, whichever way the axis points
    assert beyond_share(_at(1.0, 1), c, a, np.diag([1.0, -1.0, -1.0]), 2) == 1.0


@pytest.mark.parametrize("kind", ["floor", "wall"])
def test_a_slab_exactly_20_degrees_off_is_still_level_or_upright(kind):
    pts = _column()
    t = np.deg2rad(20.0)
    if kind == "floor":
        R = _rx(20.0)
        box = Cuboid([0.0, 0.0, 4.8], [0.3, 0.3, 0.02], R)
        assert abs(float(R[:, 2] @ DOWN)) == math.cos(math.radians(20.0))
    else:
        R = np.array([[np.cos(t), 0.0, np.sin(t)], [0.0, 1.0, 0.0], [-np.sin(t), 0.0, np.cos(t)]])
        box = Cuboid([0.7, 0.0, 6.25], [0.02, 0.5, 0.3], R)
        assert abs(float(R[:, 0] @ DOWN)) == math.sin(math.radians(20.0))
    assert cuboid_kind(pts, box, DOWN, VIEW) == kind

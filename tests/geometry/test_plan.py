"""A room's plan (cuboidcli.geometry.plan): its convex outline from above and the share of a box beyond it."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.geometry.gravity import level_frame
from cuboidcli.geometry.plan import SAMPLES, inside_convex, room_outline, share_beyond

UP = np.array([0.0, 0.0, 1.0])


def _room(up_axis=2):
    """A 4 x 3 m room's floor and walls as points, with up along ``up_axis``."""
    g = np.random.default_rng(0)
    floor = np.c_[g.uniform(0, 4, 3000), g.uniform(0, 3, 3000), np.zeros(3000)]
    walls = np.c_[g.choice([0.0, 4.0], 1000), g.uniform(0, 3, 1000), g.uniform(0, 2.5, 1000)]
    pts = np.concatenate([floor, walls, [[0, 0, 0], [4, 0, 0], [0, 3, 0], [4, 3, 0]]])
    return np.roll(pts, up_axis - 2, axis=1)


def test_points_inside_on_and_outside_a_square():
    square = np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 1.0], [0.0, 1.0]])
    xy = np.array([[0.5, 0.5], [1.0, 0.5], [0.0, 0.0], [1.01, 0.5], [0.5, -0.01], [-0.5, 2.0]])
    assert inside_convex(square, xy).tolist() == [True, True, True, False, False, False]


def test_the_outline_is_the_rooms_corners_seen_from_above():
    outline = room_outline(_room(), level_frame(UP))
    assert sorted(map(tuple, outline.round(3).tolist())) == [(0, 0), (0, 3), (4, 0), (4, 3)]


@pytest.mark.parametrize("up_axis", [2, 1, 0])
def test_the_share_of_a_box_beyond_the_rooms_outline(up_axis):
    up = np.eye(3)[up_axis]
    level = level_frame(up)
    outline = room_outline(_room(up_axis), level)

    def box(center, half, yaw=0.0):
        c, s = np.cos(yaw), np.sin(yaw)
        turn = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])
        lift = np.roll(np.eye(3), up_axis - 2, axis=0)  # level (x, y, z up) -> this room's axes
        return lift @ np.asarray(center, float), np.asarray(half, float), lift @ turn

    assert share_beyond(*box([2, 1.5, 0.5], [0.5, 0.5, 0.5]), outline, level) == 0.0
    # across the wall at x = 4: the samples beyond it are those with x > 4 (on the wall counts inside)
    across = box([4.0, 1.5, 1.0], [0.6, 1.0, 1.0])
    assert share_beyond(*across, outline, level) == pytest.approx((SAMPLES // 2) / SAMPLES)
    beyond = box([4.5, 1.5, 1.0], [0.4, 1.0, 1.0])
    assert share_beyond(*beyond, outline, level) == 1.0
    turned = box([2.0, 1.5, 1.0], [0.5, 0.5, 1.0], np.radians(45))  # inside whatever its heading
    assert share_beyond(*turned, outline, level) == 0.0
    assert share_beyond(*beyond, outline[:2], level) == 0.0  # an outline without area


def test_the_outline_holds_every_point_to_within_its_strips():
    """The outline is the hull of the strips' end points: every point lies inside it or at most a strip's
    width out, and its corners are points of the cloud."""
    from cuboidcli.geometry.plan import OUTLINE_CELL_M, convex_hull_2d

    g = np.random.default_rng(3)
    pts = np.c_[g.normal(0, 1.5, (20000, 2)) @ [[1.0, 0.4], [0.0, 0.6]], g.uniform(0, 2, 20000)]
    outline = room_outline(pts, level_frame(UP))
    edges = np.roll(outline, -1, axis=0) - outline
    normals = np.c_[edges[:, 1], -edges[:, 0]] / np.linalg.norm(edges, axis=1)[:, None]  # outward (ccw)
    out = ((pts[:, None, :2] - outline[None]) * normals[None]).sum(-1).max(1)
    assert out.max() <= OUTLINE_CELL_M  # not the exact hull, but within a strip of it
    assert set(map(tuple, outline)) <= set(map(tuple, pts[:, :2]))
    exact = convex_hull_2d(pts[:, :2])
    assert abs(len(outline) - len(exact)) <= 5
    assert room_outline(pts[:0], level_frame(UP)).shape == (0, 2)  # no points, no outline
    assert len(room_outline(pts[:2], level_frame(UP))) == 2


def test_a_triangle_is_an_outline_too():
    """Three points outline a triangle, counter-clockwise whatever their order; a box over its long edge lies
    half beyond it."""
    from cuboidcli.geometry.plan import convex_hull_2d

    tri = np.array([[4.0, 0.0, 0.0], [0.0, 0.0, 0.0], [0.0, 4.0, 0.0]])
    outline = room_outline(tri, level_frame(UP))
    assert len(outline) == 3 and len(convex_hull_2d(tri[::-1, :2])) == 3
    assert inside_convex(outline, np.array([[1.0, 1.0], [3.0, 3.0]])).tolist() == [True, False]
    across = (np.array([2.0, 2.0, 0.0]), np.array([0.5, 0.5, 0.5]), np.eye(3))  # centred on x + y = 4
    share = share_beyond(*across, outline, level_frame(UP))
    assert 0.4 < share < 0.5  # the samples on the edge count inside

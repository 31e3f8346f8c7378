"""The room scoring kernels in numbers (cuboidcli/geometry/room.py): the value of a point for a cuboid in each
visibility, worked out by hand from the paper's f_I, the leaky occlusion penalty and the point's place in the
box's frame; gains over a state, the blocks a hypothesis visits (its near zone, lines of sight through it)
and pruning at its threshold; the blocks themselves; the rotation, surface loss and Adam refinement of the
room backend.

Every test runs in numba or with NUMBA_DISABLE_JIT=1 (how ``scripts/mutation.py`` runs them), so distances
stay under a metre or two: Python's ``math.exp`` overflows where numba's gives inf."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cuboidcli.geometry.room import _MODE, RoomPoints, room_gains, room_params, room_values
from cuboidcli.geometry.room_refine import _rodrigues, _surface_loss, refine_surface_adam
from cuboidcli.geometry.room_value import at_most, block_local, meets_local

TAU, BETA, TAU_C = 0.02, 5.0, 0.04
PARAMS = room_params(TAU, BETA, TAU_C)
CUTOFF = TAU * (1.0 + 40.0 / BETA)  # 0.18 m^2


def f_i(d2: float) -> float:
    """The soft inlier count sigmoid(beta (1 - d^2 / tau))."""
    return 1.0 / (1.0 + math.exp(-BETA * (1.0 - d2 / TAU)))


# the leaky penalty f_O: 1 - f_I below tau_c, then the tangent line at tau_c
_FC = f_i(TAU_C)
SLOPE = BETA / TAU * _FC * (1.0 - _FC)
OFFSET = 1.0 - _FC - SLOPE * TAU_C


def occluding(d2: float) -> float:
    """f_I - f_O of a side at squared distance d2 (f_I taken as 0 beyond the cutoff)."""
    f_o = 1.0 - f_i(d2) if d2 < TAU_C else SLOPE * d2 + OFFSET
    return (f_i(d2) if d2 < CUTOFF else 0.0) - f_o


def _rot(ax: float, az: float) -> np.ndarray:
    """A rotation about x by ``ax`` then about z by ``az`` (degrees): every entry differs from 0 and 1."""
    a, b = np.deg2rad(ax), np.deg2rad(az)
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    rz = np.array([[np.cos(b), -np.sin(b), 0], [np.sin(b), np.cos(b), 0], [0, 0, 1]])
    return rz @ rx


CENTER = np.array([1.0, 2.0, 3.0])
R = _rot(30.0, 40.0)


def world(local, c=CENTER, rot=R) -> np.ndarray:
    return c + np.asarray(local, dtype=np.float64) @ rot.T


def values(visibility, local_points, half, local_views=None, c=CENTER, rot=R):
    pts = world(local_points, c, rot)
    views = None if local_views is None else world(local_views, c, rot)
    room = RoomPoints.build(pts, views, visibility)
    v = room_values(room, c[None], np.asarray(half, dtype=np.float64)[None], rot[None], PARAMS)[0]
    out = np.empty_like(v)
    out[room.order] = v  # back to the input's order
    return out


def test_the_kernels_scalars_are_the_paper_s_constants():
    beta, inv_tau, tau_c, slope, offset, cutoff = PARAMS
    assert (beta, inv_tau, tau_c) == (5.0, 50.0, 0.04)
    assert slope == pytest.approx(SLOPE) and offset == pytest.approx(OFFSET)
    assert cutoff == pytest.approx(0.18)


HALF = np.array([0.4, 0.3, 0.2])
# points in the box's frame and their squared distance to its surface: on a face, 10 cm off a face on each
# side (negative coordinates too), off an edge by 10 cm along two axes, and out of reach
OUTSIDE = [
    ((0.4, 0.0, 0.0), 0.0),
    ((0.5, 0.0, 0.0), 0.01),
    ((-0.5, 0.1, 0.0), 0.01),
    ((0.0, -0.4, 0.05), 0.01),
    ((0.1, 0.0, -0.3), 0.01),
    ((0.5, 0.4, 0.0), 0.02),
    ((-0.5, 0.0, 0.3), 0.02),
    ((1.0, 0.0, 0.0), 0.36),
]
INSIDE = [((0.25, 0.05, 0.0), 0.15**2), ((-0.1, 0.2, 0.05), 0.1**2), ((0.0, 0.0, -0.12), 0.08**2)]


@pytest.mark.parametrize("visibility", ["plain", "inside"])
def test_a_point_outside_the_box_counts_f_i_of_its_distance_to_the_surface(visibility):
    local = [p for p, _ in OUTSIDE]
    expected = [f_i(d2) if d2 < CUTOFF else 0.0 for _, d2 in OUTSIDE]
    assert values(visibility, local, HALF) == pytest.approx(expected, abs=1e-12)


def test_a_point_inside_the_box_counts_as_an_inlier_in_plain_and_against_it_in_inside():
    local = [p for p, _ in INSIDE]
    assert values("plain", local, HALF) == pytest.approx([f_i(d2) for _, d2 in INSIDE], abs=1e-12)
    assert values("inside", local, HALF) == pytest.approx([occluding(d2) for _, d2 in INSIDE], abs=1e-12)
    # deeper: on the leaky penalty's line (d^2 between tau_c and the cutoff) and beyond the cutoff
    big = np.array([0.6, 0.5, 0.45])
    deep = [(0.1, 0.0, 0.2), (0.0, 0.0, 0.0)]  # 25 and 45 cm from the nearest face
    got = values("inside", deep, big)
    assert got == pytest.approx([occluding(0.0625), occluding(0.2025)], abs=1e-12)
    assert got[1] == pytest.approx(-(SLOPE * 0.2025 + OFFSET))
    assert got[0] < 0 and got[1] < got[0]


def test_a_point_exactly_on_any_face_is_an_inlier_not_inside():
    # an unturned box with half-sizes that are binary fractions: points exactly on each face
    c, half, eye = np.array([1.0, 2.0, 3.0]), np.array([0.5, 0.25, 0.125]), np.eye(3)
    local = [(0.5, 0.0, 0.0), (0.1, -0.25, 0.0), (0.0, 0.1, 0.125), (-0.5, 0.2, -0.1)]
    for visibility in ("plain", "inside"):
        assert values(visibility, local, half, c=c, rot=eye) == pytest.approx([f_i(0.0)] * 4, abs=1e-15)


A_VIEW = np.array([0.6, 0.5, 0.45])
POINT = (0.65, 0.0, 0.0)  # 5 cm off the +x face


@pytest.mark.parametrize(
    "view, expected",
    [
        ((1.5, 0.0, 0.0), f_i(0.0025)),  # seen from the same side: nothing on the line of sight
        ((0.5, 0.0, 0.0), 2 * f_i(0.0025) - 1),  # inside by 10 cm: a positive f_I - f_O, no penalty
        ((0.55, 0.0, 0.0), 2 * f_i(0.0025) - 1),  # inside by 5 cm: as the point's own side
        ((0.3, 0.1, -0.05), occluding(0.09)),  # inside by 30 cm along x
        ((-0.1, -0.35, 0.1), occluding(0.0225)),  # by 15 cm along y
        ((0.1, 0.2, -0.3), occluding(0.0225)),  # by 15 cm along z
        ((-1.0, 0.0, 0.0), occluding(1.25**2)),  # outside, looking through the box: its far side
    ],
)
def test_views_a_point_seen_through_the_box_or_from_inside_it(view, expected):
    got = values("views", [POINT], A_VIEW, [view])
    assert got == pytest.approx([expected], abs=1e-12)


def test_each_cuboid_has_its_own_row_of_values():
    pts = world([(0.5, 0.0, 0.0), (0.0, 0.4, 0.0), (0.0, 0.0, 0.3)])
    room = RoomPoints.build(pts, None, "plain")
    centers = np.stack([CENTER, CENTER + R[:, 1] * 0.1])  # the second moved 10 cm along its own y
    got = room_values(room, centers, np.stack([HALF, HALF]), np.stack([R, R]), PARAMS)
    assert got.shape == (2, 3)
    want = {
        0: [f_i(0.01), f_i(0.01), f_i(0.01)],
        1: [f_i(0.01), f_i(0.0), f_i(0.01)],
    }
    for h in range(2):
        assert got[h][np.argsort(room.order)] == pytest.approx(want[h], abs=1e-12)


def _gains(room, state_in_input_order, c, a, rot, **kw):
    state = np.asarray(state_in_input_order, dtype=np.float64)[room.order]
    return room_gains(room, state, c, a, rot, PARAMS, **kw)


def test_a_gain_joins_each_value_with_the_state():
    # four points 10 cm off the +x face (value f_I(0.01) = 0.92) over states 0, 0.5, 0.95 and -0.2
    pts = world([(0.5, 0.0, 0.0)] * 4)
    room = RoomPoints.build(pts, None, "plain")
    v = f_i(0.01)
    got = _gains(room, [0.0, 0.5, 0.95, -0.2], CENTER[None], HALF[None], R[None])
    assert got == pytest.approx([v + (v - 0.5)])
    # a point deep inside, against a state of 0.3 (inside: its negative value replaces the state)
    pts = world([(0.0, 0.0, 0.0)])
    room = RoomPoints.build(pts, None, "inside")
    big = np.array([0.6, 0.5, 0.45])
    got = _gains(room, [0.3], CENTER[None], big[None], R[None])
    assert got == pytest.approx([occluding(0.2025) - 0.3])


def test_a_point_15_cm_off_a_small_box_is_in_its_near_zone():
    """The near zone is the bounding box grown by the cutoff's distance (42 cm): a lone block of points 15 cm
    off a face is visited though no point lies within the box's own bounding box."""
    half = np.array([0.1, 0.1, 0.1])
    eye = np.eye(3)
    pts = world([(0.25, 0.0, 0.0), (0.25, 0.02, 0.0)], rot=eye)
    room = RoomPoints.build(pts, None, "plain")
    got = _gains(room, [0.0, 0.0], CENTER[None], half[None], eye[None])
    assert got == pytest.approx([2 * f_i(0.0225)])


def _box_surface(half, step=0.1):
    """Points (in the box's frame) on all six faces of a box."""
    out = []
    for k in range(3):
        i, j = [a for a in range(3) if a != k]
        u = np.arange(-half[i], half[i] + 1e-9, step)
        w = np.arange(-half[j], half[j] + 1e-9, step)
        uu, ww = np.meshgrid(u, w)
        for s in (-1.0, 1.0):
            p = np.zeros((uu.size, 3))
            p[:, i], p[:, j], p[:, k] = uu.ravel(), ww.ravel(), s * half[k]
            out.append(p)
    return np.concatenate(out)


def _reference(points, c, a, rot):
    """Plain f_I of each point's distance to the box surface, in numpy."""
    loc = (points - c) @ rot
    q = np.abs(loc) - a
    out2 = (np.maximum(q, 0.0) ** 2).sum(1)
    depth = np.maximum(-q.max(1), 0.0)
    d2 = out2 + depth**2
    return np.where(d2 < CUTOFF, 1.0 / (1.0 + np.exp(-BETA * (1.0 - d2 / TAU))), 0.0)


def test_a_turned_box_visits_every_block_of_its_faces():
    """A box 2.4 x 1.6 x 1.2 m turned about two axes, its six faces sampled every 10 cm plus points 10 cm
    off them: the blocks around every face, corner and edge are visited, and the gain is the sum of every
    point's value."""
    half = np.array([1.2, 0.8, 0.6])
    surface = _box_surface(half)
    off = surface * 1.08  # a little outside each face
    pts = world(np.concatenate([surface, off]))
    room = RoomPoints.build(pts, None, "plain")
    assert len(room.start) - 1 > 20
    want = _reference(pts, CENTER, half, R).sum()
    got = _gains(room, np.zeros(len(pts)), CENTER[None], half[None], R[None])
    assert got == pytest.approx([want], rel=1e-12)
    # three hypotheses at once (one per row), the middle one the box
    c3 = np.stack([CENTER + 5.0, CENTER, CENTER - 5.0])
    got = _gains(room, np.zeros(len(pts)), c3, np.stack([half] * 3), np.stack([R] * 3))
    assert got == pytest.approx([0.0, want, 0.0], abs=1e-9)


def _turned(ax: float, ay: float, az: float) -> np.ndarray:
    a, b, g = np.deg2rad([ax, ay, az])
    rx = np.array([[1, 0, 0], [0, np.cos(a), -np.sin(a)], [0, np.sin(a), np.cos(a)]])
    ry = np.array([[np.cos(b), 0, np.sin(b)], [0, 1, 0], [-np.sin(b), 0, np.cos(b)]])
    rz = np.array([[np.cos(g), -np.sin(g), 0], [np.sin(g), np.cos(g), 0], [0, 0, 1]])
    return rz @ ry @ rx


CYCLE = np.array([[0.0, 0.0, 1.0], [1.0, 0.0, 0.0], [0.0, 1.0, 0.0]])  # the axes permuted: a proper rotation
SMALL = _turned(10.0, 8.0, 12.0)


@pytest.mark.parametrize("rot", [_turned(45.0, 20.0, 45.0), SMALL, CYCLE @ SMALL, CYCLE.T @ SMALL])
def test_the_corners_of_a_big_turned_box_are_in_its_near_zone(rot):
    """Its bounding box reaches each corner: a point on every corner of a box 4 x 5 x 6 m turned about all
    three axes (by much, or a little from each order of the axes), each corner its own
    block, counts f_I(0)."""
    assert np.allclose(rot @ rot.T, np.eye(3)) and np.linalg.det(rot) == pytest.approx(1.0)
    half = np.array([2.0, 2.5, 3.0])
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=np.float64)
    pts = world(signs * half, CENTER, rot)
    room = RoomPoints.build(pts, None, "plain")
    assert len(room.start) - 1 == 8
    got = _gains(room, np.zeros(8), CENTER[None], half[None], rot[None])
    assert got == pytest.approx([8 * f_i(0.0)])


def test_views_visit_blocks_whose_lines_of_sight_cross_the_box():
    """Points 1 m behind a box seen through it from the other side are far from its near zone, but their
    lines of sight cross it: each counts the penalty of the far side (1.3 m away)."""
    half = np.array([0.3, 0.3, 0.3])
    local = np.array([[1.3, 0.0, 0.0], [1.3, 0.05, 0.0], [1.3, 0.0, -0.05]])
    views = np.tile([-1.0, 0.0, 0.0], (3, 1))
    pts, v = world(local), world(views)
    room = RoomPoints.build(pts, v, "views")
    got = _gains(room, np.zeros(3), CENTER[None], half[None], R[None])
    assert got == pytest.approx([3 * occluding(1.6**2)])
    # seen from beside the box, they add nothing; nor without viewpoints
    room = RoomPoints.build(pts, world(np.tile([1.3, 1.0, 0.0], (3, 1))), "views")
    assert _gains(room, np.zeros(3), CENTER[None], half[None], R[None]) == pytest.approx([0.0])
    room = RoomPoints.build(pts, None, "plain")
    assert _gains(room, np.zeros(3), CENTER[None], half[None], R[None]) == pytest.approx([0.0])


def _two_blocks():
    """10 points 10 cm past the +x face of a box (well explained) and, in another block on the -x side,
    5 points 30 cm out (worth almost nothing): bounds 10 and 5 over a zero state."""
    half = np.array([0.2, 0.2, 0.2])
    good = np.c_[np.full(10, 0.3), np.linspace(-0.1, 0.1, 10), np.zeros(10)]
    poor = np.c_[np.full(5, -0.5), np.linspace(-0.1, 0.1, 5), np.zeros(5)]
    pts = world(np.concatenate([good, poor]))
    room = RoomPoints.build(pts, None, "plain")
    assert len(room.start) == 3
    gain = 10 * f_i(0.01) + 5 * f_i(0.09)
    return room, half, gain


def test_pruning_abandons_only_hypotheses_that_cannot_reach_the_threshold():
    room, half, gain = _two_blocks()
    args = (np.zeros(15), CENTER[None], half[None], R[None])
    assert _gains(room, *args) == pytest.approx([gain])
    # a threshold it reaches keeps it exact
    assert _gains(room, *args, prune_below=gain - 0.01) == pytest.approx([gain])
    # a threshold above the bound of what it visits prunes it at once
    assert _gains(room, *args, prune_below=15.5).tolist() == [-np.inf]
    # the better block is visited first: after it, 9.2 + 5 cannot reach 14.5 but can reach 12 (the worse
    # block first, 0 + 10 could not)
    assert _gains(room, *args, prune_below=14.5).tolist() == [-np.inf]
    assert _gains(room, *args, prune_below=12.0) == pytest.approx([gain])
    # the bound given is the one used
    bound = room.block_bound(np.zeros(15))
    assert _gains(room, *args, prune_below=14.5, bound=bound * 2).tolist() == pytest.approx([gain])
    # nothing left to gain (every point inside another box) is not below a threshold of 0
    assert _gains(room, np.full(15, -0.5), *args[1:], prune_below=0.0).tolist() == [0.0]


def test_pruning_counts_only_the_blocks_a_hypothesis_visits():
    """A block far from the box (bound 8) adds nothing to what the box can still gain: a threshold over the
    10 of its own block prunes it."""
    half = np.array([0.2, 0.2, 0.2])
    good = np.c_[np.full(10, 0.3), np.linspace(-0.1, 0.1, 10), np.zeros(10)]
    far = np.c_[np.full(8, 3.0), np.linspace(-0.1, 0.1, 8), np.zeros(8)]
    pts = world(np.concatenate([good, far]))
    room = RoomPoints.build(pts, None, "plain")
    state = np.zeros(18)
    got = _gains(room, state, CENTER[None], half[None], R[None], prune_below=12.0)
    assert got.tolist() == [-np.inf]
    assert _gains(room, state, CENTER[None], half[None], R[None]) == pytest.approx([10 * f_i(0.01)])


def _inside_and_near_the_face(n_face: int, n_deep: int):
    """An "inside" room: ``n_face`` points 10 cm inside a face of a box of half-size 0.8 m (within the
    inlier margin of 0.42 m: inliers) and ``n_deep`` points at its centre (0.8 m deep: against it), in two
    blocks."""
    half = np.full(3, 0.8)
    face = np.c_[np.full(n_face, 0.7), np.linspace(-0.01, 0.01, n_face), np.zeros(n_face)]
    deep = np.zeros((n_deep, 3))
    room = RoomPoints.build(world(np.concatenate([face, deep])), None, "inside")
    assert len(room.start) == 2 + (n_deep > 0)
    return room, half, n_face * occluding(0.01) + n_deep * occluding(0.64)


def test_a_block_inside_a_box_but_within_the_margin_of_its_face_can_still_gain():
    room, half, gain = _inside_and_near_the_face(10, 0)
    args = (np.zeros(10), CENTER[None], half[None], R[None])
    assert _gains(room, *args) == pytest.approx([gain])
    assert _gains(room, *args, prune_below=gain - 0.01) == pytest.approx([gain])


def test_a_box_is_scored_first_on_the_blocks_deep_inside_it():
    """Points deeper inside than the inlier margin can only count against the box: their block is scored
    before the blocks that might gain (here the one of larger bound), so a box that hides them is abandoned
    at once."""
    room, half, gain = _inside_and_near_the_face(10, 5)
    args = (np.zeros(15), CENTER[None], half[None], R[None])
    assert gain < 0
    assert _gains(room, *args) == pytest.approx([gain])
    # the face's block alone reaches 8.4: scored first, it would keep the box past a threshold of 8
    assert _gains(room, *args, prune_below=8.0).tolist() == [-np.inf]
    assert _gains(room, *args, prune_below=gain - 0.01) == pytest.approx([gain])


def _most(visibility, local_points, local_views=None, half=(0.8, 0.8, 0.8), near=True):
    """What any point of a one-block room can add at most for the box of ``half`` at CENTER, R."""
    views = None if local_views is None else world(local_views)
    room = RoomPoints.build(world(local_points), views, visibility)
    assert len(room.start) == 2
    args = (room.lo, room.hi, room.view_lo, room.view_hi, 0, *CENTER, R, *half, PARAMS)
    return at_most(*args, _MODE[visibility], near)


# a block of points 0.7-0.72 m deep inside the box of half-size 0.8 m (the inlier margin is 0.42 m) and one
# 5-7 cm inside its +x face
DEEP = np.c_[np.zeros(3), [-0.02, 0.0, 0.1], np.zeros(3)]
AT_FACE = np.c_[[0.73, 0.74, 0.75], np.zeros(3), np.zeros(3)]


def test_a_point_deep_inside_a_box_adds_at_most_the_penalty_at_the_block_s_least_depth():
    # "inside": each deep point counts f_IO of its depth, the least of which is 0.7 m (loosened by a
    # millionth)
    most = _most("inside", DEEP)
    assert most == pytest.approx(occluding(0.7**2) * (1 - 1e-6), rel=1e-9)
    assert occluding(0.7**2) < most < -1.7
    # "views", seen from outside the box: hidden by the side the line of sight leaves through
    outside = np.tile([1.5, 0.0, 0.0], (3, 1))
    assert _most("views", DEEP, outside) == pytest.approx(most)
    # "plain": nothing counts against a box, and a point beyond the margin adds nothing
    assert _most("plain", DEEP) == 0.0
    # seen from just inside the box (5 cm, within sqrt(tau) = 14 cm): the line of sight never leaves the box,
    # the viewpoint's penalty is not yet below 0
    shallow = np.tile([0.75, 0.0, 0.0], (3, 1))
    assert _most("views", DEEP, shallow) == 0.0
    # viewpoints both inside and outside the box: only 0 is sure
    mixed = np.array([[0.78, 0.1, 0.1], [0.82, 0.1, 0.1], [0.9, 0.1, 0.1]])
    assert _most("views", DEEP, mixed) == 0.0


def test_a_point_seen_from_deep_inside_a_box_adds_at_most_the_viewpoint_s_penalty():
    # points at the face (inliers on their own) seen from 0.5 m inside: a viewpoint inside the box is
    # penalised by its depth, here at least 0.3 m
    inside = np.c_[[0.2, 0.25, 0.3], np.zeros(3), np.zeros(3)]
    most = _most("views", AT_FACE, inside)
    assert occluding(0.5**2) <= most <= occluding(0.3**2) * (1 - 1e-6) + 1e-12
    # and so does a block reached by lines of sight alone
    assert _most("views", AT_FACE + [0.6, 0, 0], inside, near=False) == pytest.approx(most)


def test_a_block_s_depth_is_that_of_its_bounding_box_on_the_box_s_shallowest_axis():
    # points spread 15 cm either way along y, in a box 0.6 m deep along y and 0.8 m along x and z: 0.45 m
    wide = np.c_[np.zeros(3), [-0.15, 0.0, 0.15], np.zeros(3)]
    assert _most("inside", wide, half=(0.8, 0.6, 0.8)) == pytest.approx(occluding(0.45**2) * (1 - 1e-6))
    # viewpoints spread 5 cm either way along z, 0.1 m off the middle along y, in a box 0.5 m deep along z
    views = np.c_[np.zeros(3), np.full(3, 0.1), [-0.05, 0.0, 0.05]]
    assert _most("views", AT_FACE, views, half=(0.8, 0.8, 0.5)) == pytest.approx(
        occluding(0.45**2) * (1 - 1e-6)
    )


def test_a_block_in_a_box_s_frame_is_its_centre_s_offset_and_the_half_extents_of_its_turned_bounds():
    lo, hi = np.array([[1.8, 2.9, 3.8]]), np.array([[2.2, 3.2, 4.3]])
    got = np.array(block_local(lo, hi, 0, *CENTER, R))
    centre, half = (lo[0] + hi[0]) / 2, (hi[0] - lo[0]) / 2
    assert got[:3] == pytest.approx(np.abs(R.T @ (centre - CENTER)))
    assert got[3:] == pytest.approx(np.abs(R.T) @ half)
    # the block meets the box only where it does along each of the box's axes
    a = np.abs(R.T @ (centre - CENTER)) - np.abs(R.T) @ half  # how far the block stays off each face pair
    assert (a > 0.3).all()
    for k in range(3):
        half_size = np.full(3, 5.0)
        half_size[k] = a[k] - 0.01
        assert not meets_local(lo, hi, 0, *CENTER, R, *half_size)
        half_size[k] = a[k] + 0.01
        assert meets_local(lo, hi, 0, *CENTER, R, *half_size)


def test_a_block_within_the_margin_of_the_surface_may_gain_and_one_beyond_it_may_not():
    assert _most("views", AT_FACE, AT_FACE + [0.5, 0, 0]) == 1.0
    assert _most("inside", AT_FACE) == 1.0
    # 0.3 m deep is within the margin of 0.42 m
    assert _most("plain", np.c_[np.full(3, 0.5), [0.0, 0.01, 0.02], np.zeros(3)]) == 1.0
    # seen from 1-3 cm, or 12-14 cm, inside the box (less than sqrt(tau) = 14 cm): the viewpoint's penalty is
    # not below 0
    assert _most("views", AT_FACE, AT_FACE + [0.04, 0.1, 0.1]) == 1.0
    assert _most("views", AT_FACE, AT_FACE + [-0.07, 0.1, 0.1]) == 1.0
    assert _most("views", AT_FACE + [0.6, 0, 0], AT_FACE + [1.0, 0, 0], near=False) == 0.0


def test_a_block_s_held_points_are_those_of_state_at_least_0():
    room = RoomPoints.build(world(AT_FACE), None, "plain")
    state = np.array([0.5, -0.2, 0.0])[room.order]
    assert room.block_held(state).tolist() == [[2.0, 0.5]]


def test_views_pruning_keeps_a_box_that_reaches_the_threshold_past_points_deep_inside_it():
    """Points deep inside, seen from outside: their block counts against the box by no more than its bound,
    and a box that still reaches the threshold is kept. The other block, 10 points 1 cm off the face, can
    gain at most 10 and gains 9.93: a bound of the deep block's 2 points lower than 2 f_IO(0.64) by 0.07
    would abandon the box."""
    on_face = np.c_[np.full(10, 0.81), np.linspace(-0.01, 0.01, 10), np.zeros(10)]
    views = np.concatenate([np.tile([1.2, 0.0, 0.0], (10, 1)), np.tile([0.0, 0.0, 1.5], (2, 1))])
    room = RoomPoints.build(world(np.concatenate([on_face, np.zeros((2, 3))])), world(views), "views")
    assert len(room.start) == 3
    half = np.full(3, 0.8)
    exact = _gains(room, np.zeros(12), CENTER[None], half[None], R[None])[0]
    assert exact == pytest.approx(10 * f_i(0.0001) + 2 * occluding(0.64))
    got = _gains(room, np.zeros(12), CENTER[None], half[None], R[None], prune_below=exact - 1e-6)
    assert got.tolist() == [exact]


def test_pruning_keeps_a_box_past_points_deep_inside_it_that_another_box_explains():
    """In "plain" visibility a point deep inside the box adds 0 whatever its state: the deep block's 4
    points of state 0.5 take nothing from the box, which a bound of n (0 - state) would say they do."""
    on_face = np.c_[np.full(10, 0.81), np.linspace(-0.01, 0.01, 10), np.zeros(10)]
    room = RoomPoints.build(world(np.concatenate([on_face, np.zeros((4, 3))])), None, "plain")
    assert len(room.start) == 3
    half = np.full(3, 0.8)
    state = np.r_[np.zeros(10), np.full(4, 0.5)]
    exact = _gains(room, state, CENTER[None], half[None], R[None])[0]
    assert exact == pytest.approx(10 * f_i(0.0001))
    got = _gains(room, state, CENTER[None], half[None], R[None], prune_below=exact - 1e-6)
    assert got.tolist() == [exact]


def test_views_pruning_counts_only_the_blocks_seen_through_or_near_the_box():
    # 5 points 10 cm off the box (one block, bound 5) and one 2.8 m away (bound 1), each seen from beside
    # itself: the far block is neither near nor seen through the box, so a threshold of 5.3 prunes the box
    # (with that block counted, 4.6 + 1 could still reach it)
    half = np.array([0.2, 0.2, 0.2])
    good = np.c_[np.full(5, 0.3), np.linspace(-0.01, 0.01, 5), np.zeros(5)]
    local = np.concatenate([good, [[3.0, 0.0, 0.0]]])
    views = np.concatenate([np.tile([0.8, 0.0, 0.0], (5, 1)), [[3.5, 0.0, 0.0]]])
    room = RoomPoints.build(world(local), world(views), "views")
    assert len(room.start) == 3
    got = _gains(room, np.zeros(6), CENTER[None], half[None], R[None], prune_below=5.3)
    assert got.tolist() == [-np.inf]
    assert _gains(room, np.zeros(6), CENTER[None], half[None], R[None]) == pytest.approx([5 * f_i(0.01)])


def test_blocks_are_half_metre_cells_and_viewpoint_cells():
    pts = np.array([[0.1, 0.0, 0.0], [0.45, 0.2, 0.3], [0.7, 0.0, 0.0], [0.2, 0.55, 0.0], [0.3, 0.1, 0.49]])
    room = RoomPoints.build(pts, None, "inside")
    assert np.array_equal(room.points, pts[room.order])
    assert np.array_equal(room.views, np.zeros_like(pts))
    blocks = [sorted(room.order[a:b].tolist()) for a, b in zip(room.start[:-1], room.start[1:], strict=True)]
    assert sorted(blocks) == [[0, 1, 4], [2], [3]]
    b = [i for i, blk in enumerate(blocks) if blk == [0, 1, 4]][0]
    assert room.lo[b] == pytest.approx([0.1, 0.0, 0.0]) and room.hi[b] == pytest.approx([0.45, 0.2, 0.49])
    assert np.array_equal(room.hull_lo, room.lo) and np.array_equal(room.hull_hi, room.hi)
    # a block two cells along x is not the one a cell along y
    more = RoomPoints.build(np.concatenate([pts, [[1.2, 0.0, 0.0]]]), None, "plain")
    blocks = [sorted(more.order[a:b].tolist()) for a, b in zip(more.start[:-1], more.start[1:], strict=True)]
    assert sorted(blocks) == [[0, 1, 4], [2], [3], [5]]
    with pytest.raises(dataclasses.FrozenInstanceError):
        more.visibility = "views"  # type: ignore[misc]
    # the cells start at the points' minimum, wherever that is
    shifted = RoomPoints.build(pts + [0.3, -0.2, 7.0], None, "plain")
    assert np.array_equal(np.diff(shifted.start), np.diff(room.start))
    # with viewpoints, one block per half-metre cell of the viewpoints too
    views = np.array([[0.0, 0.0, 1.0], [0.1, 0.1, 1.1], [0.0, 0.0, 1.0], [0.0, 0.0, 1.0], [0.0, 0.6, 1.0]])
    room = RoomPoints.build(pts, views, "views")
    assert np.array_equal(room.views, views[room.order])
    blocks = [sorted(room.order[a:b].tolist()) for a, b in zip(room.start[:-1], room.start[1:], strict=True)]
    assert sorted(blocks) == [[0, 1], [2], [3], [4]]
    b = [i for i, blk in enumerate(blocks) if blk == [0, 1]][0]
    assert room.hull_lo[b] == pytest.approx([0.0, 0.0, 0.0]) and room.hull_hi[b] == pytest.approx(
        [0.45, 0.2, 1.1]
    )
    assert room.lo[b] == pytest.approx([0.1, 0.0, 0.0]) and room.hi[b] == pytest.approx([0.45, 0.2, 0.3])
    b = [i for i, blk in enumerate(blocks) if blk == [4]][0]
    assert room.hull_lo[b] == pytest.approx([0.0, 0.1, 0.49]) and room.hull_hi[b] == pytest.approx(
        [0.3, 0.6, 1.0]
    )
    # the blocks of one half-metre voxel together: their voxel, its boxes those of its blocks together
    voxel_of = {tuple(blk): int(room.voxel[i]) for i, blk in enumerate(blocks)}
    assert voxel_of[(0, 1)] == voxel_of[(4,)] != voxel_of[(2,)] != voxel_of[(3,)] != voxel_of[(0, 1)]
    v = voxel_of[(4,)]
    assert room.voxel_lo[v] == pytest.approx([0.1, 0.0, 0.0]) and room.voxel_hi[v] == pytest.approx(
        [0.45, 0.2, 0.49]
    )
    assert room.voxel_hull_lo[v] == pytest.approx([0.0, 0.0, 0.0])
    assert room.voxel_hull_hi[v] == pytest.approx([0.45, 0.6, 1.1])
    # the cells are the caller's to choose
    coarse = RoomPoints.build(pts, views, "views", block_m=1.0, view_cell_m=5.0)
    assert np.array_equal(coarse.start, [0, 5]) and np.array_equal(coarse.voxel, [0])


def test_views_need_one_viewpoint_per_point_and_visibility_is_checked():
    pts = np.zeros((3, 3))
    with pytest.raises(ValueError, match="viewpoint"):
        RoomPoints.build(pts, None, "views")
    with pytest.raises(ValueError, match="viewpoint"):
        RoomPoints.build(pts, np.zeros((2, 3)), "views")
    with pytest.raises(ValueError, match="visibility"):
        RoomPoints.build(pts, None, "seen")
    RoomPoints.build(pts, np.ones((3, 3)), "views")


def test_a_subsample_keeps_every_step_th_point_of_each_block():
    pts = np.r_[np.tile([0.1, 0.1, 0.1], (5, 1)), np.tile([1.1, 0.1, 0.1], (3, 1))]
    room = RoomPoints.build(pts, None, "plain")
    keep, sub = room.subsample(2)
    assert keep.tolist() == [0, 2, 4, 5, 7]
    assert sub.start.tolist() == [0, 3, 5]
    assert np.array_equal(sub.points, room.points[keep]) and np.array_equal(sub.order, room.order[keep])
    assert np.array_equal(sub.lo, room.lo) and sub.visibility == "plain"
    keep, sub = room.subsample(4)
    assert keep.tolist() == [0, 4, 5] and sub.start.tolist() == [0, 2, 3]


def test_a_block_s_bound_is_what_its_points_can_still_gain():
    pts = np.r_[np.tile([0.1, 0.1, 0.1], (4, 1)), np.tile([1.1, 0.1, 0.1], (2, 1))]
    room = RoomPoints.build(pts, None, "plain")
    # negative states are final (a point inside a solid box); 0 can gain 1, 0.2 can gain 0.8, 1.3 nothing
    bound = room.block_bound(np.array([-0.5, 0.2, 1.3, 0.0, 0.5, 0.25]))
    assert bound == pytest.approx([1.8, 1.25])


def _cv_rodrigues(r):
    import cv2

    return cv2.Rodrigues(np.asarray(r, dtype=np.float64))[0]


def test_the_refinement_s_rotation_is_rodrigues():
    for r in ([0.3, -0.5, 0.7], [2.0, 0.1, -1.0], [0.0, 0.0, 1e-3], [-0.2, 0.4, 0.0]):
        assert _rodrigues(*r) == pytest.approx(_cv_rodrigues(r), abs=1e-12)
    assert np.array_equal(_rodrigues(0.0, 0.0, 0.0), np.eye(3))


def test_the_surface_loss_is_the_mean_squared_distance_to_the_faces():
    x = np.r_[CENTER, 0.0, 0.0, 0.0, 1.0, 0.5, 0.25]
    local = np.array(
        [[2.0, 0.0, 0.0], [0.0, -1.0, 0.0], [0.5, 0.0, 0.1], [1.5, 0.0, -0.5], [-0.5, 0.0, -0.15]]
    )
    # 1 m out along x; 50 cm out along -y; inside, 15 and 10 cm from a z face; off an edge by 0.5 and 0.25
    grad = np.full(9, 7.0)
    loss = _surface_loss(CENTER + local, x, grad)
    assert loss == pytest.approx((1.0 + 0.25 + 0.0225 + 0.3125 + 0.01) / 5)
    assert np.all(grad[3:6] == 0.0)  # the rotation's gradient is left to the caller
    # the gradient in the centre and half-sizes is the loss's own
    for k in (0, 1, 2, 6, 7, 8):
        e = np.zeros(9)
        e[k] = 1e-6
        fd = _surface_loss(CENTER + local, x + e, np.zeros(9)) - _surface_loss(
            CENTER + local, x - e, np.zeros(9)
        )
        assert grad[k] == pytest.approx(fd / 2e-6, abs=1e-6)
    # turned: the same points turned with the box give the same loss
    r = np.array([0.3, -0.2, 0.5])
    rot = _cv_rodrigues(r)
    turned = CENTER + local @ rot.T
    assert _surface_loss(turned, np.r_[CENTER, r, 1.0, 0.5, 0.25], np.zeros(9)) == pytest.approx(loss)


def test_adam_refinement_moves_a_box_onto_its_surface_points_within_its_size_limits():
    half = np.array([0.5, 0.3, 0.2])
    rot = _cv_rodrigues([0.0, 0.0, 0.3])
    pts = CENTER + _box_surface(half, 0.1) @ rot.T
    truth = np.r_[CENTER, 0.0, 0.0, 0.3, half]
    assert _surface_loss(pts, truth, np.zeros(9)) == pytest.approx(0.0, abs=1e-20)
    init = truth + np.r_[0.04, -0.03, 0.02, 0.03, -0.03, 0.05, 0.04, -0.03, 0.03]
    best = refine_surface_adam(pts, init, 0.05, 2.0, 0.005, 60)
    start = _surface_loss(pts, init, np.zeros(9))
    end = _surface_loss(pts, best, np.zeros(9))
    assert end < 0.02 * start
    assert best[:3] == pytest.approx(CENTER, abs=0.01) and best[6:] == pytest.approx(half, abs=0.01)
    assert best[3:6] == pytest.approx(truth[3:6], abs=0.01)  # turned back about every axis
    # one iteration: Adam's first step moves every parameter by the learning rate against its gradient
    grad = np.zeros(9)
    _surface_loss(pts, init, grad)
    one = refine_surface_adam(pts, init, 0.05, 2.0, 0.005, 1)
    assert _surface_loss(pts, one, np.zeros(9)) < start
    for k in (0, 1, 2, 6, 7, 8):
        assert one[k] - init[k] == pytest.approx(-0.005 * np.sign(grad[k]), rel=1e-5)
    # the half-sizes stay within their limits
    for k, lo, hi, size in ((6, 0.05, 0.35, 0.35), (8, 0.28, 2.0, 0.28)):
        within = init.copy()
        within[k] = size
        got = refine_surface_adam(pts, within, lo, hi, 0.005, 60)
        assert got[k] == size and lo <= got[6:].min() and got[6:].max() <= hi
        assert _surface_loss(pts, got, np.zeros(9)) < 0.9 * _surface_loss(pts, within, np.zeros(9))
    # no iterations, or steps that only make it worse: the start is returned as it is
    assert np.array_equal(refine_surface_adam(pts, init, 0.05, 2.0, 0.005, 0), init)
    assert np.array_equal(refine_surface_adam(pts, truth, 0.05, 2.0, 0.5, 3), truth)


@pytest.mark.parametrize("axis", [0, 1])
def test_a_box_far_along_one_axis_visits_the_block_it_stands_in(axis):
    """Each axis of the near zone is tested against the block's own bounds on that axis: a box 5 m along x
    (then y) from the origin, its points around it, the other coordinates near 0 (a block whose upper bound
    on the next axis lies far below the box's lower bound on this one). The gain is the sum of the values."""
    half = np.array([0.2, 0.2, 0.2])
    eye = np.eye(3)
    centre = np.zeros(3)
    centre[axis] = 5.0
    local = [(0.2, 0.0, 0.0), (0.0, 0.2, 0.05), (0.0, 0.05, 0.2), (0.1, 0.1, 0.1)]
    pts = world(local, c=centre, rot=eye)
    room = RoomPoints.build(pts, None, "plain")
    want = room_values(room, centre[None], half[None], eye[None], PARAMS)[0].sum()
    got = _gains(room, np.zeros(len(pts)), centre[None], half[None], eye[None])
    assert want > 3.0
    assert got == pytest.approx([want])

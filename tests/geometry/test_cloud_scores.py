"""The floor evidence of a room's up direction, in numbers: a cloud built so that every direction's score is
known (a floor, one wall, clutter that faces neither), checked against the rule of
:func:`cuboidcli.geometry.cloud.floor_scores` (share of the points on the floor times the room-height
plausibility of the extent) and against each threshold of :func:`~cuboidcli.geometry.cloud.room_up` just
inside and just outside it."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.geometry.cloud import (
    ROOM_HEIGHT_M,
    TIE,
    _confidence,
    _open_floor,
    floor_normal,
    floor_scores,
    is_camera_view,
    room_up,
    settle_axis,
    voxel_groups,
)

N = 10_000
X, Y, Z = np.eye(3)


def room(floor: int = 600, wall: int = 420, height: float = 3.0, floor_z: float = 0.0, seed: int = 0):
    """``floor`` points on z = ``floor_z`` (normals +z) over 3 x 3 m, ``wall`` points on x = 0 (normals +x)
    up to ``height``, 2 % of N at z = ``height`` and the rest in between, both facing y and kept away from
    the room's sides (no direction finds a floor in them). Along z the 1st to 99th percentile of the heights
    is exactly [0, height] when ``floor_z`` is 0."""
    rng = np.random.default_rng(seed)
    top = N // 50
    bulk = N - floor - wall - top
    pts = np.concatenate(
        [
            np.c_[rng.uniform(0, 3, (floor, 2)), np.full(floor, floor_z)],
            np.c_[np.zeros(wall), rng.uniform(0, 3, wall), rng.uniform(0, height, wall)],
            np.c_[rng.uniform(0.5, 2.5, top), rng.uniform(1, 2, top), np.full(top, height)],
            np.c_[rng.uniform(0.5, 2.5, bulk), rng.uniform(1, 2, bulk), rng.uniform(0, height, bulk)],
        ]
    )
    normals = np.concatenate([np.tile(Z, (floor, 1)), np.tile(X, (wall, 1)), np.tile(Y, (top + bulk, 1))])
    return pts, normals


def along(up: np.ndarray, axis: np.ndarray) -> bool:
    """Within a degree of ``axis`` (the floor's refit takes in a few clutter points near it)."""
    return float(up @ axis) > np.cos(np.deg2rad(1.0))


def plausibility(extent: float) -> float:
    lo, full, hi = ROOM_HEIGHT_M
    return float(np.clip((extent - lo) / (full - lo), 0.0, 1.0) * min(1.0, hi / extent) ** 2)


@pytest.mark.parametrize(
    ("height", "expected"), [(0.5, 0.0), (0.9, 0.25), (1.2, 0.5), (3.0, 1.0), (8.0, 0.25)]
)
def test_a_floor_scores_its_share_times_the_plausibility_of_the_room_height(height, expected):
    assert plausibility(height) == pytest.approx(expected)
    scores = floor_scores(*room(height=height), np.eye(3))
    assert scores[4] == pytest.approx(600 / N * expected, rel=1e-9)  # +z: the floor
    assert scores[0] == pytest.approx(420 / N * plausibility(2.5), rel=0.02)  # +x: the wall, 2.5 m deep
    assert scores[[1, 2, 3, 5]].tolist() == [0.0, 0.0, 0.0, 0.0]


def test_a_plane_above_the_lowest_band_is_no_floor():
    # the clutter reaches down to z = 0: a plane a fifth of the way up is not in the lowest 15 %
    assert floor_scores(*room(floor_z=0.6), np.eye(3))[4] == 0.0
    assert floor_scores(*room(floor_z=0.3), np.eye(3))[4] > 0.05


def test_a_floor_needs_one_percent_of_the_points():
    assert floor_scores(*room(floor=120), np.eye(3))[4] == pytest.approx(0.012)
    assert floor_scores(*room(floor=80), np.eye(3))[4] == 0.0


def test_the_cloud_overrules_the_hint_only_at_twice_its_score():
    up = room_up(*room(floor=600, wall=250), hint=X)  # the floor scores 2.4 times the wall
    assert up.source == "estimated" and along(up.up, Z)
    assert up.confidence == pytest.approx(1 - 250 / 600, abs=0.01) and up.warning == ""
    kept = room_up(*room(floor=600, wall=330), hint=X)  # 1.8 times: the hint's wall normal stays up
    assert along(kept.up, X)


def test_only_a_sure_cloud_overrules_the_hint():
    """The floor must also stand clear of every other axis (confidence at least UNSURE, 0.25): a cloud torn
    between two axes that are not the hint's keeps the hint, with a warning."""
    sure = room_up(*room(floor=600, wall=420), hint=Y)  # confidence 0.3
    assert along(sure.up, Z) and sure.confidence == pytest.approx(0.3, abs=0.01) and sure.warning == ""
    edge = room_up(*room(floor=600, wall=447), hint=Y)  # confidence 0.255
    assert along(edge.up, Z) and edge.confidence == pytest.approx(0.255, abs=0.003) and edge.warning == ""
    unsure = room_up(*room(floor=600, wall=456), hint=Y)  # confidence 0.24: the hint stays up
    assert along(unsure.up, Y) and unsure.confidence == 0.0
    assert unsure.warning.startswith("up direction unsure (its floor is not clearly the lowest large plane")


def test_the_hint_s_own_axis_is_a_warning_only_in_a_tie():
    near_tie = room_up(*room(floor=600, wall=560), hint=Z)  # confidence 0.067: the hint agrees
    assert along(near_tie.up, Z) and near_tie.warning == ""
    tie = room_up(*room(floor=600, wall=582), hint=Z)  # confidence 0.03
    assert along(tie.up, Z) and tie.confidence < TIE and tie.warning.startswith("up direction unsure")


def test_an_up_axis_with_few_surfaces_far_from_the_hint_gives_way_to_it():
    estimated = room_up(*room(floor=600, wall=300), hint=Y)  # 6 % of the normals face up
    assert estimated.source == "estimated" and along(estimated.up, Z)
    assert estimated.support[0] == pytest.approx(0.06, abs=0.005)
    hinted = room_up(*room(floor=400, wall=200), hint=Y)  # 4 %: the hint, with a warning
    assert hinted.source == "hint" and along(hinted.up, Y) and hinted.confidence == 0.0
    assert "the cloud's up axis carries few surfaces" in hinted.warning


def test_a_hint_of_any_length_is_a_direction():
    hinted = room_up(*room(floor=400, wall=200), hint=5.0 * Y)
    assert hinted.source == "hint" and np.linalg.norm(hinted.up) == pytest.approx(1.0)


def test_a_given_up_without_a_manhattan_frame_has_no_support():
    pts, _ = room()
    up = room_up(pts, np.zeros_like(pts), hint=Z, given=2.0 * Y)  # no normals: no frame
    assert up.source == "given" and up.axes is None and up.support == (0.0, 0.0, 0.0)
    assert np.allclose(up.up, Y)


def test_voxel_groups_are_means_in_lexicographic_voxel_order():
    rng = np.random.default_rng(3)
    cells = np.array([(i, j, k) for i in range(3) for j in range(4) for k in range(2)])
    points = np.repeat(cells, 5, axis=0) * 0.1 + rng.uniform(0.01, 0.09, (len(cells) * 5, 3))
    points[0] = 0.01  # the lowest corner: voxels start there
    order = rng.permutation(len(points))
    means, inverse, first = voxel_groups(points[order], 0.1)
    assert len(means) == len(cells) == 24 and np.array_equal(inverse[first], np.arange(24))
    for g in range(24):
        members = points[order][inverse == g]
        assert len(members) == 5 and np.allclose(means[g], members.mean(0))
        assert np.array_equal(np.floor(members / 0.1), np.tile(cells[g], (5, 1)))  # the g-th in x, y, z order


def camera_view(front: int, hidden: int, behind_m: float) -> np.ndarray:
    """A wall 2 m in front of a camera at the origin, ``front`` points on it, and ``hidden`` points on the
    rays of the first ones, ``behind_m`` further along them."""
    rng = np.random.default_rng(1)
    rays = np.c_[rng.uniform(-0.5, 0.5, (front, 2)), np.ones(front)]
    wall = rays * 2.0
    back = wall[:hidden] * (1.0 + behind_m / np.linalg.norm(wall[:hidden], axis=1, keepdims=True))
    return np.concatenate([wall, back])


def test_a_camera_view_has_four_in_five_points_in_front():
    assert is_camera_view(camera_view(80, 20, 0.12))  # 80 % visible: a view
    assert not is_camera_view(camera_view(70, 30, 0.12))  # 70 %: surfaces behind each other
    assert is_camera_view(camera_view(70, 30, 0.08))  # within 10 cm of the front: one surface's noise
    assert not is_camera_view(camera_view(80, 0, 0.0) - [0.0, 0.0, 1.95])  # points near or behind the camera


def tilted(angle_deg: float) -> np.ndarray:
    """Z turned by ``angle_deg`` about x."""
    a = np.deg2rad(angle_deg)
    return np.array([0.0, -np.sin(a), np.cos(a)])


def test_up_becomes_the_normal_of_its_floor():
    # a floor tilted 4 degrees about x under clutter and walls, the room 1 m above the origin: the floor's
    # normal is up, not the Manhattan axis; the same room upside down has it pointing down
    rng = np.random.default_rng(5)
    pts, normals = room(floor=1500, wall=400)
    n = tilted(4.0)
    pts[:1500, 2] = -(pts[:1500, 1] * n[1]) / n[2] + rng.normal(0, 0.003, 1500)  # the plane n . p = 0
    normals[:1500] = n
    pts[:, 2] += 1.0
    for sign in (1.0, -1.0):
        flip = np.array([1.0, 1.0, sign])
        up = floor_normal(pts * flip, normals * flip, sign * Z)
        assert np.degrees(np.arccos(np.clip(up @ (n * flip), -1, 1))) < 0.3


def test_without_a_floor_up_stays_as_it_is():
    pts, normals = room(floor=15, wall=400)  # 15 points facing up: fewer than 20
    assert np.array_equal(floor_normal(pts, normals, tilted(3.0)), tilted(3.0))


def test_an_axis_settles_on_twenty_or_more_surfaces_of_either_sign():
    axis = tilted(5.0)
    for count, moved in ((19, False), (20, True)):
        normals = np.tile(axis, (count, 1))
        normals[::2] *= -1  # PCA normals come with either sign
        out = settle_axis(normals, Z)
        assert np.allclose(out, axis if moved else Z, atol=1e-12)
    # a few normals 22 degrees to the other side pull the first, widest cone; the narrower ones drop them
    normals = np.concatenate([np.tile(axis, (40, 1)), np.tile(tilted(-22.0), (10, 1))])
    assert np.allclose(settle_axis(normals, Z), axis, atol=1e-12)


def test_the_axes_start_with_up_on_every_path():
    pts, normals = room(floor=600, wall=300)
    for up in (
        room_up(pts, normals, hint=Y),  # estimated
        room_up(*room(floor=400, wall=200), hint=Y),  # the hint, few surfaces face up
        room_up(pts, normals, hint=Z, given=X),  # given
    ):
        assert up.axes is not None and np.allclose(up.axes[:, 0], up.up, atol=1e-9), up.source


def test_the_hint_wins_over_few_surfaces_from_more_than_45_degrees():
    hint = np.array([0.0, np.sin(np.deg2rad(60.0)), np.cos(np.deg2rad(60.0))])  # 60 degrees from up
    far = room_up(*room(floor=400, wall=200), hint=hint)
    assert far.source == "hint" and np.allclose(far.up, hint)
    hint = np.array([0.0, np.sin(np.deg2rad(40.0)), np.cos(np.deg2rad(40.0))])  # 40 degrees: the cloud's
    near = room_up(*room(floor=400, wall=200), hint=hint)
    assert near.source == "estimated" and along(near.up, Z)


def test_without_a_manhattan_frame_the_hint_is_up():
    pts, _ = room()
    normals = np.tile(Z, (len(pts), 1))  # one family of surfaces: no frame
    up = room_up(pts, normals, hint=Y)
    assert up.source == "hint" and up.axes is None and np.allclose(up.up, Y) and up.confidence == 0.0
    assert "no two perpendicular surfaces" in up.warning


def test_a_rough_floor_scores_its_densest_three_slices():
    # the floor spread evenly over 10 cm of height, the whole room 1 m up: the 3 cm slices of the floor
    # band hold 180 floor points each, the best three together 540 of the 600
    pts, normals = room(floor=600, wall=420)
    pts[:600, 2] = -0.05 + 0.1 * (np.arange(600) + 0.5) / 600
    pts[:, 2] += 1.0
    scores = floor_scores(pts, normals, np.eye(3))
    assert scores.shape == (6,)
    assert scores[4] == pytest.approx(540 / N, abs=2 / N)


def test_a_room_up_record():
    up = room_up(*room(floor=600, wall=300), hint=Y)
    d = up.to_dict()
    assert d["up"] == [round(float(v), 6) for v in up.up] and d["source"] == "estimated"
    assert d["confidence"] == round(up.confidence, 4) and "warning" not in d
    assert np.array(d["manhattan_frame"]).shape == (3, 3) and d["support"] == [
        round(s, 4) for s in up.support
    ]
    assert all(v == round(v, 6) for row in d["manhattan_frame"] for v in row)
    pts, _ = room()
    bare = room_up(pts, np.tile(Z, (len(pts), 1)), hint=Y)  # no frame: no axes, no support
    assert bare.support == (0.0, 0.0, 0.0)
    assert set(bare.to_dict()) == {"up", "source", "confidence", "warning"}


def floor_and_top(n_floor: int, tilt_deg: float = 4.0, n_top: int = 20, normals_up: bool = False):
    """``n_floor`` points on a floor tilted ``tilt_deg`` about x (normals along it, or along z when
    ``normals_up``), and ``n_top`` points 3 m up facing x: a bare floor under a far ceiling strip."""
    rng = np.random.default_rng(8)
    n = tilted(tilt_deg)
    xy = rng.uniform(0, [3.0, 1.0], (n_floor, 2))
    floor = np.c_[xy, -(xy[:, 1] * n[1]) / n[2]]
    top = np.c_[rng.uniform(0, 3, (n_top, 2)), np.full(n_top, 3.0)]
    normals = np.concatenate([np.tile(Z if normals_up else n, (n_floor, 1)), np.tile(X, (n_top, 1))])
    return np.concatenate([floor, top]), normals, n


def test_a_floor_needs_twenty_facing_points():
    pts, normals, n = floor_and_top(20, tilt_deg=1.0)  # all within the 3 cm of its level
    assert abs(floor_normal(pts, normals, Z) @ n) > np.cos(np.deg2rad(0.01))
    pts, normals, _ = floor_and_top(19, tilt_deg=1.0)
    assert np.array_equal(floor_normal(pts, normals, Z), Z)


def test_a_floor_of_many_points_needs_one_percent_of_them():
    pts, normals, n = floor_and_top(60, tilt_deg=1.0, n_top=9000)  # 60 of 9060 facing up: under 1 %
    assert np.array_equal(floor_normal(pts, normals, Z), Z)
    pts, normals, n = floor_and_top(120, tilt_deg=1.0, n_top=9000)
    assert abs(floor_normal(pts, normals, Z) @ n) > np.cos(np.deg2rad(0.01))


def test_a_slice_tilted_beyond_15_degrees_is_no_floor():
    # points on an 18 degree ramp whose normals claim to face up: the refit plane is the ramp, too steep
    pts, normals, _ = floor_and_top(400, tilt_deg=18.0, normals_up=True)
    assert np.array_equal(floor_normal(pts, normals, Z), Z)
    pts, normals, n = floor_and_top(400, tilt_deg=12.0, normals_up=True)
    assert abs(floor_normal(pts, normals, Z) @ n) > np.cos(np.deg2rad(0.01))


def test_a_single_point_or_a_near_wall_in_front_is_a_camera_view():
    assert is_camera_view(np.array([[0.1, 0.0, 2.0]]))
    assert is_camera_view(camera_view(80, 0, 0.0) * 0.06)  # a wall 12 cm in front
    assert not is_camera_view(camera_view(80, 0, 0.0) * 0.05)  # 10 cm: too near for a depth camera


def two_walls(floor: int, wall: int, facing: int):
    """:func:`room` with ``facing`` of its clutter points moved onto the wall across the room (x = 3 m,
    normals along x): the hint's axis x then scores ``wall`` / N less ``facing`` / N."""
    pts, normals = room(floor=floor, wall=wall)
    pts[-facing:] = np.c_[np.full(facing, 3.0), pts[-facing:, 1], pts[-facing:, 2]]
    normals[-facing:] = X
    return pts, normals


def test_a_floor_open_above_wins_over_the_convention_s_axis_from_a_margin_of_0_07():
    """Where the cloud does not overrule the input's convention (here X: the floor scores under twice the
    wall), an axis across it still wins when its score less its opposite's (the floor's: all of it, no
    ceiling) is at least OPEN_FLOOR (0.07) and more than the convention's axis's (the wall's: all of it)."""
    scores = floor_scores(*room(floor=710, wall=600), np.eye(3))
    assert scores[4] == pytest.approx(0.071) and scores[0] == pytest.approx(0.06, abs=1e-3)
    assert along(room_up(*room(floor=710, wall=600), hint=X).up, Z)
    assert along(room_up(*room(floor=700, wall=600), hint=X).up, Z)  # exactly 0.07
    assert along(room_up(*room(floor=699, wall=600), hint=X).up, X)  # 0.0699: the convention stays
    assert along(room_up(*room(floor=750, wall=740), hint=X).up, Z)
    assert along(room_up(*room(floor=750, wall=760), hint=X).up, X)  # the wall's margin is larger
    assert along(room_up(*room(floor=750, wall=750), hint=X).up, X)  # equal margins: the convention stays


def test_of_two_open_floors_across_the_convention_the_larger_margin_wins():
    # the convention names y, which scores nothing; the floor (0.09) and the wall (0.08) both qualify, and
    # neither is sure enough of itself to overrule (confidence 0.11)
    scores = floor_scores(*room(floor=900, wall=800), np.eye(3))
    assert scores[4] == pytest.approx(0.09) and scores[0] == pytest.approx(0.08, abs=1e-3)
    assert along(room_up(*room(floor=900, wall=800), hint=Y).up, Z)
    assert along(room_up(*room(floor=800, wall=900), hint=Y).up, X)


def test_an_open_floor_needs_four_fifths_of_the_convention_s_score():
    """The convention's wall faces another across the room: its margin is small, but an open floor must
    still score at least OPEN_SHARE (0.8) of it."""
    scores = floor_scores(*two_walls(floor=860, wall=1050, facing=350), np.eye(3))
    assert scores[0] == pytest.approx(0.105, abs=1e-3) and scores[1] == pytest.approx(0.035, abs=1e-3)
    assert along(room_up(*two_walls(floor=840, wall=1050, facing=350), hint=X).up, Z)  # 0.8 of it
    assert along(room_up(*two_walls(floor=838, wall=1050, facing=350), hint=X).up, X)  # 0.798 of it


def test_an_open_floor_does_not_overrule_the_cameras_up():
    assert along(room_up(*room(floor=710, wall=600), hint=X, cameras=True).up, X)
    assert along(room_up(*room(floor=710, wall=600), hint=X).up, Z)


def test_a_ceiling_seen_better_than_the_floor_does_not_turn_the_room_upside_down():
    """Only an axis across the convention's can win by its open floor: a ceiling scanned whole over a floor
    hidden by furniture reads as an open floor upside down, and the convention stays (the ceiling scores
    under twice the floor: the cloud does not overrule it)."""
    pts, normals = room(floor=800, wall=200)
    pts[-1550:, 2], normals[-1550:] = 3.0, Z  # a ceiling of 1550 points at the room's top
    scores = floor_scores(pts, normals, np.eye(3))
    assert scores[5] - scores[4] == pytest.approx(0.075, abs=1e-3) and scores[5] < 2 * scores[4]
    assert along(room_up(pts, normals, hint=Z).up, Z)
    mirrored = pts * [1.0, 1.0, -1.0]  # the same room mirrored, read with the convention -z
    assert along(room_up(mirrored, normals, hint=-Z).up, -Z)


def test_a_convention_with_no_floor_at_all_gives_way_to_its_own_axis_reversed():
    """A room stored upside down whose ceiling was not scanned: the convention's axis (-z here) has no floor
    at all, and the floor (0.09) outscores the wall (0.08) too little for the cloud to overrule. The open
    floor, its margin the largest, wins although it lies along the convention's own axis."""
    scores = floor_scores(*room(floor=900, wall=800), np.eye(3))
    assert scores[5] == 0.0 and scores[4] == pytest.approx(0.09)
    assert scores[0] == pytest.approx(0.08, abs=1e-3)
    up = room_up(*room(floor=900, wall=800), hint=-Z)
    assert along(up.up, Z) and up.source == "estimated"
    # a convention with a floor of its own is never reversed, however open the floor opposite it
    assert _open_floor(np.array([0.0, 0.0, 0.0, 0.0, 0.10, 0.02]), 5) == 5
    assert _open_floor(np.array([0.0, 0.0, 0.0, 0.0, 0.10, 0.0]), 5) == 4
    assert _open_floor(np.array([0.0, 0.0, 0.0, 0.0, 0.06, 0.0]), 5) == 5  # no floor open enough


def test_the_confidence_is_the_clearer_of_the_scores_and_the_open_floor():
    """Order +a0, -a0, +a1, -a1, +a2, -a2. A floor open above counts from OPEN_FLOOR (0.07) of margin."""
    scores = np.array([0.10, 0.0, 0.06, 0.04, 0.0, 0.0])
    # by score 1 - 0.06 / 0.10 = 0.4; by margin (0.10 against the next axis's 0.06 - 0.04) 0.8
    assert _confidence(scores, 0) == pytest.approx(0.8)
    # a margin of exactly OPEN_FLOOR counts: 1 - 0.02 / 0.07 rather than the scores' 1 - 0.06 / 0.07
    assert _confidence(np.array([0.07, 0.0, 0.06, 0.04, 0.0, 0.0]), 0) == pytest.approx(5 / 7)
    # a margin of 0.05 is no floor open above: the scores alone, and the wall outscores it
    assert _confidence(np.array([0.05, 0.0, 0.06, 0.045, 0.0, 0.0]), 0) == 0.0
    # a ceiling as large as the floor: no margin, the scores alone
    assert _confidence(np.array([0.10, 0.10, 0.06, 0.04, 0.0, 0.0]), 0) == 0.0
    assert _confidence(np.array([0.10, 0.0, 0.0, 0.0, 0.0, 0.0]), 0) == 1.0
    assert _confidence(np.zeros(6), 0) == 0.0

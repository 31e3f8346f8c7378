"""More of a room before it is fitted (cuboidcli/geometry/cloud.py), in numbers: where voxels start, the
room-up record, an axis settling in its cones, a floor tilted 12 degrees or with normals spread 12 degrees,
a skirting board 5 cm above the floor, a floor of exactly 1 % of the points, rays through distinct and shared
image cells, three planes crossing at their centres (no floor in any direction), and the free side of
plates between others a few decimetres away."""

from __future__ import annotations

import dataclasses

import numpy as np
import pytest

from cuboidcli.geometry.cloud import (
    RoomUp,
    _reorder,
    _support,
    estimate_normals,
    floor_normal,
    floor_scores,
    is_camera_view,
    room_up,
    settle_axis,
    voxel_groups,
)
from cuboidcli.geometry.free_side import _free_lengths, free_side_normals
from tests.geometry.test_cloud_scores import N, room, tilted
from tests.geometry.test_free_side import INSIDE, box_room, plate

X, Y, Z = np.eye(3)


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.degrees(np.arccos(np.clip(abs(a @ b) / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))))


def test_voxels_start_at_the_lowest_point():
    # within half a metre of the lowest corner in every axis: one voxel, wherever the corner lies
    pts = np.array([[0.3, 0.3, 0.3], [0.5, 0.4, 0.35], [0.75, 0.7, 0.7]])
    for shift in (0.0, -5.2, 11.7):
        means, inverse, first = voxel_groups(pts + shift, 0.5)
        assert len(means) == 1 and inverse.tolist() == [0, 0, 0] and first.tolist() == [0]
        assert means[0] == pytest.approx(pts.mean(0) + shift)


def test_the_room_up_record_rounds_and_is_frozen():
    up = RoomUp(
        np.array([0.12345678, -0.2, 0.9]), np.eye(3), "estimated", (0.123456, 0.5, 0.376544), 0.654321, "w"
    )
    assert up.to_dict() == {
        "up": [0.123457, -0.2, 0.9],
        "source": "estimated",
        "confidence": 0.6543,
        "warning": "w",
        "manhattan_frame": [[1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]],
        "support": [0.1235, 0.5, 0.3765],
    }
    assert RoomUp(Z, None, "hint", confidence=0.0).to_dict() == {
        "up": [0.0, 0.0, 1.0],
        "source": "hint",
        "confidence": 0.0,
    }
    with pytest.raises(dataclasses.FrozenInstanceError):
        up.confidence = 1.0  # type: ignore[misc]


def test_an_axis_settles_in_cones_of_25_15_and_8_degrees():
    # 40 normals along z and 40 at 20 degrees: the widest cone takes both (their bisector, 10 degrees), the
    # narrower ones keep it; a cone of 17.8 degrees would have kept z
    normals = np.concatenate([np.tile(Z, (40, 1)), np.tile(tilted(20.0), (40, 1))])
    assert settle_axis(normals, Z) == pytest.approx(tilted(10.0), abs=1e-12)
    # 40 along z and 20 at 15 degrees: the mean is 5 degrees off z, and the 8 degree cone around it keeps
    # only the normals along z
    normals = np.concatenate([np.tile(Z, (40, 1)), np.tile(tilted(15.0), (20, 1))])
    assert settle_axis(normals, Z) == pytest.approx(Z, abs=1e-12)
    # 15 along z and 10 at 30 degrees: under 20 within 25 degrees, the axis stays as it is
    normals = np.concatenate([np.tile(Z, (15, 1)), np.tile(tilted(30.0), (10, 1))])
    assert np.array_equal(settle_axis(normals, Z), Z)


def test_a_floor_tilted_12_degrees_from_the_guess_gives_its_own_normal():
    # a floor on the plane n . p = 0 (rising 64 cm over its 3 m), a wall x = 0 from 70 cm up, a ceiling
    rng = np.random.default_rng(8)
    n = tilted(12.0)
    floor = np.c_[rng.uniform(0, 3, (1500, 2)), np.zeros(1500)]
    floor[:, 2] = -(floor[:, 1] * n[1]) / n[2]
    wall = np.c_[np.zeros(400), rng.uniform(0, 3, 400), rng.uniform(0.7, 3.0, 400)]
    ceiling = np.c_[rng.uniform(0, 3, (300, 2)), np.full(300, 3.0)]
    pts = np.concatenate([floor, wall, ceiling])
    normals = np.concatenate([np.tile(n, (1500, 1)), np.tile(X, (400, 1)), np.tile(Z, (300, 1))])
    up = floor_normal(pts, normals, Z)
    assert angle_deg(up, n) < 1e-6 and up @ Z > 0


def test_floor_normals_spread_12_degrees_about_up_still_face_it():
    pts, normals = room(floor=600, wall=420)
    normals[:600:2] = tilted(12.0)
    normals[1:600:2] = tilted(-12.0)
    scores = floor_scores(pts, normals, np.eye(3))
    assert scores[4] == pytest.approx(600 / N, rel=1e-9)


def _floor_and_skirting(strip: int = 60):
    """A floor z = 0 of 1500 points over 3 x 3 m, a wall x = 0 from 10 cm up, the ceiling z = 3, and
    ``strip`` points of a skirting board on x = 3 between 5 and 6 cm above the floor."""
    rng = np.random.default_rng(7)
    floor = np.c_[rng.uniform(0, 3, (1500, 2)), np.zeros(1500)]
    wall = np.c_[np.zeros(400), rng.uniform(0, 3, 400), rng.uniform(0.1, 3.0, 400)]
    ceiling = np.c_[rng.uniform(0, 3, (300, 2)), np.full(300, 3.0)]
    skirting = np.c_[np.full(strip, 3.0), rng.uniform(0, 3, strip), rng.uniform(0.05, 0.06, strip)]
    pts = np.concatenate([floor, wall, ceiling, skirting])
    normals = np.concatenate(
        [np.tile(Z, (1500, 1)), np.tile(X, (400, 1)), np.tile(Z, (300, 1)), np.tile(X, (strip, 1))]
    )
    return pts, normals


def test_points_5_cm_above_the_floor_are_not_part_of_its_plane():
    pts, normals = _floor_and_skirting()
    up = floor_normal(pts, normals, tilted(5.0))
    assert angle_deg(up, Z) < 1e-6


def test_a_floor_of_exactly_one_percent_of_the_points_scores():
    assert floor_scores(*room(floor=100), np.eye(3))[4] == pytest.approx(0.01, rel=1e-12)
    assert floor_scores(*room(floor=99), np.eye(3))[4] == 0.0


def _ray(u: int, v: int, depth: float) -> np.ndarray:
    """A point at ``depth`` (m) along the ray through the middle of image cell (u, v) of 0.01 rad."""
    d = np.array([(u + 0.5) * 0.01, (v + 0.5) * 0.01, 1.0])
    return depth * d / np.linalg.norm(d)


def test_points_on_distinct_rays_are_all_in_front_whatever_their_depths():
    # three rows of 18 cells (v = 2, -2 and -3): near points in the lowest row (1 m), nearer than those of the
    # middle row (1.5 m) and the top row (3 m, 10 cm deeper each cell to the right); no point hides another
    cols = range(18)
    pts = np.array(
        [_ray(u, 2, 1.0) for u in cols]
        + [_ray(u, -2, 1.5) for u in cols]
        + [_ray(u, -3, 3.0 + 0.1 * u) for u in cols]
    )
    assert is_camera_view(pts)
    # the far ones moved onto the near ones' rays are hidden: 36 of 54 in front
    hidden = np.array([_ray(u, 2, 1.0) for u in cols] + [_ray(u, 2, 3.0 + 0.1 * u) for u in cols])
    assert not is_camera_view(np.concatenate([hidden, pts[18:36]]))


def test_points_behind_each_other_on_one_ray_are_no_camera_view():
    assert not is_camera_view(np.array([_ray(0, 0, 1.0), _ray(0, 0, 3.0), _ray(0, 0, 3.05)]))
    assert is_camera_view(np.array([_ray(0, 0, 1.0), _ray(0, 0, 1.05), _ray(0, 0, 1.1)]))


def _crossing_planes(n: int = 1200):
    """Three 2 x 2 m planes through the origin, one per axis: no direction has a floor (each one's lowest
    band holds only the two other planes' edges, facing across)."""
    rng = np.random.default_rng(11)
    out, normals = [], []
    for k in range(3):
        p = rng.uniform(-1, 1, (n, 3))
        p[:, k] = 0.0
        out.append(p)
        normals.append(np.tile(np.eye(3)[k], (n, 1)))
    return np.concatenate(out), np.concatenate(normals)


def test_a_cloud_without_a_floor_keeps_the_hint_s_axis_with_no_confidence():
    pts, normals = _crossing_planes()
    assert floor_scores(pts, normals, np.eye(3)).tolist() == [0.0] * 6
    for hint in (X, Y, Z, -Y):
        up = room_up(pts, normals, hint)
        assert up.confidence == 0.0 and up.source == "estimated"
        assert up.up @ hint == pytest.approx(1.0)
        assert up.warning.startswith("up direction unsure (its floor is not clearly")


def test_the_frame_column_nearest_up_comes_first():
    frame = np.stack([tilted(30.0), X, np.cross(tilted(30.0), X)], axis=1)
    assert np.array_equal(_reorder(frame, Y), frame[:, [2, 0, 1]])
    assert np.array_equal(_reorder(frame, -X), frame[:, [1, 0, 2]])
    assert np.array_equal(_reorder(frame, Z), frame)


def test_alike_sides_turn_a_plate_towards_the_point_inside():
    # a plate in the middle of the room: 2 m of room on either side
    room_pts, part = box_room(), plate(2.0)
    pts = np.concatenate([room_pts, part])
    normals = np.tile(X, (len(pts), 1))
    centre = len(room_pts) + int(np.argmin(np.linalg.norm(part - [2.0, 2.0, 1.5], axis=1)))
    for inside, facing in (([1.0, 2.0, 1.5], -X), ([2.6, 2.0, 1.5], X), ([3.6, 2.0, 1.5], X)):
        out = free_side_normals(pts, normals, np.array(inside), 0.1)
        assert out[centre].tolist() == facing.tolist()


def test_a_plate_30_cm_from_one_and_60_cm_from_another_keeps_its_side():
    # in front (towards the point inside) another plate 30 cm away, behind one 60 cm away: the back is freer,
    # but by less than a quarter of the 2 m the rays look
    room_pts, part = box_room(), plate(2.0)
    pts = np.concatenate([room_pts, part, plate(2.3), plate(1.4)])
    normals = np.tile(X, (len(pts), 1))
    centre = len(room_pts) + int(np.argmin(np.linalg.norm(part - [2.0, 2.0, 1.5], axis=1)))
    out = free_side_normals(pts, normals, np.array([3.6, 2.0, 1.5]), 0.1)
    assert out[centre].tolist() == X.tolist()
    # with the one behind 1.1 m away, the back wins by more than the margin
    pts = np.concatenate([room_pts, part, plate(2.3), plate(0.9)])
    out = free_side_normals(pts, normals, np.array([3.6, 2.0, 1.5]), 0.1)
    assert out[centre].tolist() == (-X).tolist()


def test_the_support_follows_the_reordered_columns():
    frame = np.stack([tilted(30.0), X, np.cross(tilted(30.0), X)], axis=1)
    support = np.array([0.5, 0.3, 0.2])
    assert _support(support, frame, Y) == (0.2, 0.5, 0.3)
    assert _support(support, frame, X) == (0.3, 0.5, 0.2)
    assert _support(support, None, Y) == (0.0, 0.0, 0.0)


def test_the_second_cone_is_15_degrees():
    # 15 normals along z, 10 at 21 degrees and 10 at -24 degrees: the widest cone takes all (0.83 degrees
    # off z); 15 degrees around that holds only the first 15, under 20, so the axis stays there (a cone of
    # 22.5 degrees would take the 21-degree ones too and move to 8.4 degrees)
    normals = np.concatenate(
        [np.tile(Z, (15, 1)), np.tile(tilted(21.0), (10, 1)), np.tile(tilted(-24.0), (10, 1))]
    )
    out = settle_axis(normals, Z)
    first = normals.sum(0) / np.linalg.norm(normals.sum(0))
    assert out == pytest.approx(first, abs=1e-12) and angle_deg(out, Z) < 1.0


def _tilted_room(floor_z: float = 0.0, strays: int = 0, seed: int = 9):
    """A floor tilted 4 degrees at height ``floor_z`` (1500 points), a wall x = 0 from 70 cm up, a ceiling 3 m
    above, and ``strays`` points scattered 1 m under the floor (normals along y)."""
    rng = np.random.default_rng(seed)
    n = tilted(4.0)
    floor = np.c_[rng.uniform(0, 3, (1500, 2)), np.zeros(1500)]
    floor[:, 2] = -(floor[:, 1] * n[1]) / n[2]
    wall = np.c_[np.zeros(400), rng.uniform(0, 3, 400), rng.uniform(0.7, 3.0, 400)]
    ceiling = np.c_[rng.uniform(0, 3, (300, 2)), np.full(300, 3.0)]
    below = np.c_[rng.uniform(0, 3, (strays, 2)), np.full(strays, -1.0)]
    pts = np.concatenate([floor, wall, ceiling, below]) + [0.0, 0.0, floor_z]
    normals = np.concatenate(
        [np.tile(n, (1500, 1)), np.tile(X, (400, 1)), np.tile(Z, (300, 1)), np.tile(Y, (strays, 1))]
    )
    return pts, normals, n


def test_the_floor_band_is_measured_from_the_first_percentile_wherever_the_room_is():
    # the room 3 m below the origin, and 0.7 % of the points strays 1 m under its floor (noise through a
    # mirror): the floor still lies in the lowest 15 % and is refitted to its own normal
    for floor_z, strays in ((-3.0, 0), (0.0, 16), (2.0, 16)):
        pts, normals, n = _tilted_room(floor_z, strays)
        assert angle_deg(floor_normal(pts, normals, Z), n) < 1e-6
        scores = floor_scores(pts, normals, np.eye(3))
        assert scores[4] > 0.6 and scores[4] == scores.max()


def test_a_surface_whose_normals_lie_beyond_15_degrees_of_up_is_no_floor_to_refit():
    # a plane 3 degrees off level whose estimated normals are 17 and 23 degrees off: kept as the guess
    pts, normals, _ = _tilted_room()
    normals[:1500:2] = tilted(-17.0)
    normals[1:1500:2] = tilted(23.0)
    assert np.array_equal(floor_normal(pts, normals, Z), Z)


def test_a_few_facing_points_under_the_floor_do_not_move_its_level():
    # 30 facing points 15 cm under a level floor: the floor's slices are the densest, and the 30 points
    # and the skirting board are left out of its plane
    pts, normals = _floor_and_skirting()
    rng = np.random.default_rng(12)
    sunk = np.c_[rng.uniform(1, 2, (30, 2)), np.full(30, -0.15)]
    pts = np.concatenate([pts, sunk])
    normals = np.concatenate([normals, np.tile(Z, (30, 1))])
    assert angle_deg(floor_normal(pts, normals, tilted(0.5)), Z) < 1e-6


def test_points_exactly_3_cm_from_the_floor_s_level_are_not_part_of_its_plane():
    # the level of a floor at z = 0 is the middle of its 3 cm slice, 1.5 cm: points at 4.5 cm are 3 cm off
    pts, normals = _floor_and_skirting(strip=0)
    edge = np.c_[np.full(40, 3.0), np.linspace(0, 3, 40), np.full(40, 0.045)]
    pts = np.concatenate([pts, edge])
    normals = np.concatenate([normals, np.tile(X, (40, 1))])
    assert np.array_equal(np.abs(floor_normal(pts, normals, Z)), Z)


def test_a_point_exactly_10_cm_behind_the_nearest_on_its_ray_is_the_same_surface():
    assert is_camera_view(np.array([[0.0, 0.0, 0.125], [0.0, 0.0, 0.225]]))
    assert not is_camera_view(np.array([[0.0, 0.0, 0.125], [0.0, 0.0, 0.2251]]))


def _camera_room(pitch_deg: float, roll_deg: float):
    """A room 4 x 2.7 x 5 m (x right, y down, z forward; floor 1.5 m under the camera) as a depth image of a
    camera pitched and rolled by the given angles: (points, normals, the room's up) in the camera's frame."""
    p, r = np.deg2rad(pitch_deg), np.deg2rad(roll_deg)
    pitch = np.array([[1, 0, 0], [0, np.cos(p), -np.sin(p)], [0, np.sin(p), np.cos(p)]])
    roll = np.array([[np.cos(r), -np.sin(r), 0], [np.sin(r), np.cos(r), 0], [0, 0, 1]])
    rot = pitch @ roll  # camera to world
    u, v = np.meshgrid(np.linspace(-0.6, 0.6, 60), np.linspace(-0.45, 0.45, 45))
    rays = np.c_[u.ravel(), v.ravel(), np.ones(u.size)]
    rays /= np.linalg.norm(rays, axis=1, keepdims=True)
    world = rays @ rot.T
    lo, hi = np.array([-2.0, -1.2, -1.0]), np.array([2.0, 1.5, 4.0])
    with np.errstate(divide="ignore"):
        t = np.where(world > 0, hi / world, lo / world)
    t[~np.isfinite(t) | (t <= 0)] = np.inf
    axis = t.argmin(1)
    depth = t.min(1)
    pts = rays * depth[:, None]
    normals = np.eye(3)[axis] @ rot  # the face's normal in the camera's frame
    return pts, normals, np.array([0.0, -1.0, 0.0]) @ rot


@pytest.mark.parametrize(("pitch", "roll"), [(-10.0, 0.0), (10.0, 0.0), (0.0, -10.0), (0.0, 10.0)])
def test_a_depth_image_in_its_camera_s_frame_takes_the_axis_nearest_the_camera_s_up(pitch, roll):
    pts, normals, up = _camera_room(pitch, roll)
    assert is_camera_view(pts)
    got = room_up(pts, normals, hint=Z)  # the file's convention is not asked
    assert got.source == "camera" and angle_deg(got.up, up) < 1.0 and got.up @ up > 0


def _grid_with_walls():
    occupied = np.zeros((20, 20, 20), dtype=np.bool_)
    occupied[15, :, :] = True  # cells 15: x in [1.3, 1.4) from the origin -0.2
    occupied[:, 12, :] = True  # y in [0.9, 1.0) from -0.3
    occupied[:, :, 17] = True  # z in [1.3, 1.4) from -0.4
    return occupied


def test_a_ray_s_cell_is_counted_from_the_grid_s_origin_on_each_axis():
    origin = np.array([-0.2, -0.3, -0.4])
    point = np.array([[0.33, 0.27, 0.41]])
    dirs = np.eye(3)[None]  # +x, +y, +z
    out = np.empty((1, 3))
    _free_lengths(point, dirs, _grid_with_walls(), origin, 0.1, 0.2, 2.0, out)
    # from 0.2 m on in half-cell steps: x reaches 1.3 at t = 0.97 (step 1.0), y 0.9 at 0.63 (0.65), z 1.3
    # at 0.89 (0.9)
    assert out[0] == pytest.approx([1.0, 0.65, 0.9])
    # in the opposite directions the rays leave the grid: nothing is known to be free there
    _free_lengths(point, -dirs, _grid_with_walls(), origin, 0.1, 0.2, 2.0, out)
    assert out[0].tolist() == [0.0, 0.0, 0.0]


def test_behind_the_scanned_space_nothing_is_free():
    # the floor with a table top 30 cm above it, and the wall x = 4 with a plate 30 cm in front of it:
    # their backs lie outside the scanned space (2 cells of margin), so they keep facing the room
    room_pts = box_room()
    g = np.arange(1.5, 2.5001, 0.1)
    a, b = np.meshgrid(g, g, indexing="ij")
    table = np.c_[a.ravel(), b.ravel(), np.full(a.size, 0.3)]
    pts = np.concatenate([room_pts, table, plate(3.7)])
    normals = np.zeros_like(pts)
    normals[(pts[:, 2] == 0.0) | (pts[:, 2] == 0.3)] = Z
    normals[(pts[:, 0] == 4.0) | (np.abs(pts[:, 0] - 3.7) < 1e-9)] = X
    normals[np.linalg.norm(normals, axis=1) == 0] = Y
    out = free_side_normals(pts, normals, INSIDE, 0.1)
    under = np.flatnonzero(
        (pts[:, 2] == 0.0) & (np.abs(pts[:, 0] - 2.0) < 0.2) & (np.abs(pts[:, 1] - 2.0) < 0.2)
    )
    behind = np.flatnonzero(
        (pts[:, 0] == 4.0) & (np.abs(pts[:, 1] - 2.0) < 0.2) & (np.abs(pts[:, 2] - 1.5) < 0.2)
    )
    assert len(under) and len(behind)
    assert (out[under] == Z).all() and (out[behind] == -X).all()


def test_a_point_inside_on_the_plate_s_own_plane_keeps_the_sign_given():
    room_pts, part = box_room(), plate(2.0)
    pts = np.concatenate([room_pts, part])
    centre = len(room_pts) + int(np.argmin(np.linalg.norm(part - [2.0, 2.0, 1.5], axis=1)))
    for given in (X, -X):
        out = free_side_normals(pts, np.tile(given, (len(pts), 1)), np.array([2.0, 0.5, 0.5]), 0.1)
        assert out[centre].tolist() == given.tolist()


def test_a_normal_comes_from_the_24_nearest_neighbours():
    # a point with 23 neighbours on the plane z = 0 within 3 cm and one more 4.5 cm away, 2 cm above it
    g = np.arange(-2, 3) * 0.01
    a, b = np.meshgrid(g, g)
    plane = np.c_[a.ravel(), b.ravel(), np.zeros(a.size)]
    plane = plane[np.argsort(np.linalg.norm(plane, axis=1), kind="stable")][:24]
    pts = np.concatenate([plane, [[0.04, 0.0, 0.02]]])
    assert abs(estimate_normals(pts, 1.0)[0] @ Z) == pytest.approx(1.0, abs=1e-9)
    assert abs(estimate_normals(pts, 1.0, max_nn=25)[0] @ Z) < 1 - 1e-6


def test_a_normal_exactly_on_a_cone_s_edge_is_outside_it():
    # 40 normals along z and 40 exactly 25 degrees off: the first cone holds only those along z
    normals = np.concatenate([np.tile(Z, (40, 1)), np.tile(tilted(25.0), (40, 1))])
    assert np.array_equal(settle_axis(normals, Z), Z)
    # a floor whose normals are exactly 15 degrees off either way faces no axis: no floor, nothing to refit
    pts, normals = room(floor=600, wall=420)
    normals[:600:2], normals[1:600:2] = tilted(15.0), tilted(-15.0)
    assert floor_scores(pts, normals, np.eye(3))[4] == 0.0
    pts, normals, _ = _tilted_room()
    normals[:1500] = tilted(15.0)
    assert np.array_equal(floor_normal(pts, normals, Z), Z)


def test_a_confidence_of_exactly_the_unsure_bar_is_no_warning():
    # the floor 600 points, the wall 450: 1 - 450 / 600 = 0.25 exactly
    up = room_up(*room(floor=600, wall=450), hint=Y)
    assert along_z(up.up) and up.confidence == 0.25 and up.warning == ""


def along_z(v: np.ndarray) -> bool:
    return angle_deg(v, Z) < 1.0 and v @ Z > 0


def test_a_ray_is_free_to_its_cap_unless_it_leaves_the_grid_first():
    # a grid of 5 x 5 x 5 cells of 0.5 m, rays from 1 m on in steps of 0.25 m up to 2 m
    occupied = np.zeros((5, 5, 5), dtype=np.bool_)
    out = np.empty((1, 1))
    for k in range(3):
        d = np.eye(3)[k][None, None]
        # at t = 1.75 the ray is still in the last cell (2.35 m), at 2 m (the cap, not taken) it would be out
        inside = np.full((1, 3), 1.2)
        inside[0, k] = 0.6
        _free_lengths(inside, d, occupied, np.zeros(3), 0.5, 1.0, 2.0, out)
        assert out[0, 0] == 2.0
        # at t = 1.75 it is at 2.55 m, in the cell just past the grid: it has left, nothing is known there
        leaving = np.full((1, 3), 1.2)
        leaving[0, k] = 0.8
        _free_lengths(leaving, d, occupied, np.zeros(3), 0.5, 1.0, 2.0, out)
        assert out[0, 0] == 0.0

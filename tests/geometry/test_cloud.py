"""The up direction of a bare cloud (cuboidcli.geometry.cloud.room_up): the floor decides, the hint breaks
near ties, a depth image in a camera's frame takes the camera's up."""

from __future__ import annotations

import numpy as np

from cuboidcli.geometry.cloud import estimate_normals, floor_scores, is_camera_view, room_up, voxel_groups
from cuboidcli.geometry.gravity import level_frame

Z = np.array([0.0, 0.0, 1.0])


def _plane(rng, origin, e1, e2, n):
    uv = rng.uniform(0, 1, (n, 2))
    return np.asarray(origin) + uv[:, :1] * np.asarray(e1) + uv[:, 1:] * np.asarray(e2)


def _room(size=(6.0, 5.0, 2.5), floor=12000, wall=3000, seed=0, ceiling=0):
    """Points (N, 3), z up, of a room's floor, four walls, a 1.2 x 0.6 x 0.75 m table and ``ceiling``
    points on its ceiling."""
    rng = np.random.default_rng(seed)
    x, y, z = size
    parts = [
        _plane(rng, [0, 0, 0], [x, 0, 0], [0, y, 0], floor),
        _plane(rng, [0, 0, 0], [x, 0, 0], [0, 0, z], wall),
        _plane(rng, [0, y, 0], [x, 0, 0], [0, 0, z], wall),
        _plane(rng, [0, 0, 0], [0, y, 0], [0, 0, z], wall),
        _plane(rng, [x, 0, 0], [0, y, 0], [0, 0, z], wall),
        _plane(rng, [2.0, 2.0, 0.75], [1.2, 0, 0], [0, 0.6, 0], 800),
        _plane(rng, [0, 0, z], [x, 0, 0], [0, y, 0], ceiling),
    ]
    pts = np.concatenate(parts)
    return pts + rng.normal(0, 0.003, pts.shape)


def _up(points, hint=Z):
    means = voxel_groups(points, 0.05)[0]
    return room_up(means, estimate_normals(means, 0.15), hint)


def _angle(a, b) -> float:
    return float(np.degrees(np.arccos(np.clip(a @ b, -1.0, 1.0))))


def test_a_room_s_floor_gives_its_up_with_confidence():
    up = _up(_room())
    assert _angle(up.up, Z) < 0.5 and up.source == "estimated"
    assert up.confidence > 0.25 and not up.warning
    assert up.to_dict()["confidence"] == round(up.confidence, 4) and "warning" not in up.to_dict()
    np.testing.assert_allclose(up.axes[:, 0], up.up)


def test_a_clear_floor_overrides_a_wrong_hint():
    turn = level_frame(np.array([0.0, 1.0, 0.0]))  # the room stored y up, read with the z-up convention
    up = _up(_room() @ turn.T)
    assert _angle(up.up, turn[:, 2]) < 0.5 and up.source == "estimated"


def test_a_floor_the_walls_nearly_tie_with_is_sure_when_nothing_faces_it():
    """A floor and four tall walls, no ceiling: the floor scores little more than a wall, but each wall faces
    another one and the floor nothing, so the cloud is sure of it. With a ceiling as large as the floor the
    two tie: the input's own up picks, with a warning."""
    room = _room(size=(4.0, 3.0, 2.5), floor=8000, wall=5000)
    means = voxel_groups(room, 0.05)[0]
    normals = estimate_normals(means, 0.15)
    ok = np.linalg.norm(normals, axis=1) > 0.5
    scores = np.sort(floor_scores(means[ok], normals[ok], np.eye(3)))
    assert 1.0 - scores[-2] / scores[-1] < 0.25  # by the scores alone: unsure
    up = _up(room)
    assert _angle(up.up, Z) < 1.0 and up.confidence > 0.9 and not up.warning
    closed = _up(_room(size=(4.0, 3.0, 2.5), floor=8000, wall=5000, ceiling=8000))
    assert _angle(closed.up, Z) < 1.0 and closed.confidence < 0.25 and "up direction unsure" in closed.warning


def test_in_a_near_tie_the_hint_decides_and_is_reported_unsure():
    # a closed cube of a room with a bare floor: every face looks like a floor; the hint picks
    room = _room(size=(3.0, 3.0, 3.0), floor=3000, wall=3000, ceiling=3000)
    for hint in (Z, np.array([1.0, 0.0, 0.0])):
        up = _up(room, hint)
        assert _angle(up.up, hint) < 1.0 and up.confidence < 0.25
        assert "up direction unsure" in up.warning and "--up" in up.warning


def test_a_floor_open_above_wins_over_a_wall_the_convention_names():
    """The same cube without its ceiling: the floor and the walls score alike, but only the floor has
    nothing facing it (a scan seldom holds its ceiling; each wall faces another). A file read with the
    wrong convention (up along a wall) is still fitted floor-down, and sure of it."""
    room = _room(size=(3.0, 3.0, 3.0), floor=3000, wall=3000)
    for hint in (Z, np.array([1.0, 0.0, 0.0]), np.array([0.0, -1.0, 0.0])):
        up = _up(room, hint)
        assert _angle(up.up, Z) < 1.0 and up.source == "estimated"
        assert up.confidence > 0.9 and not up.warning


def _depth_view(seed=0):
    """A camera's view (x right, y down, z forward) of a wall 2.5 m ahead with a ceiling strip above and
    a sofa-like block in front of it: what a single RGB-D frame of a room's corner gives."""
    rng = np.random.default_rng(seed)
    parts = [
        _plane(rng, [-1.5, -1.0, 2.5], [3.0, 0, 0], [0, 2.2, 0], 8000),  # the wall, y from -1 to 1.2
        _plane(rng, [-1.5, -1.0, 1.8], [3.0, 0, 0], [0, 0, 0.7], 1500),  # the ceiling strip at y = -1
        _plane(rng, [-1.0, 0.8, 1.7], [2.0, 0, 0], [0, 0, 0.7], 1200),  # the seat's top, y = 0.8
        _plane(rng, [-1.0, 0.8, 1.7], [2.0, 0, 0], [0, 0.4, 0], 800),  # the seat's front
    ]
    pts = np.concatenate(parts)
    return pts + rng.normal(0, 0.002, pts.shape)


def test_a_depth_image_in_its_camera_s_frame_takes_the_camera_s_up():
    view = _depth_view()
    assert is_camera_view(view)
    up = _up(view)
    assert _angle(up.up, np.array([0.0, -1.0, 0.0])) < 2.0 and up.source == "camera"
    assert up.to_dict()["source"] == "camera"


def test_a_room_around_its_origin_is_no_camera_view():
    room = _room()
    assert not is_camera_view(room - room.mean(0))
    assert not is_camera_view(room + [0.0, 0.0, 5.0])  # in front of the origin, but walls hide each other


def test_a_single_plane_keeps_the_hint_with_a_warning():
    rng = np.random.default_rng(0)
    plane = _plane(rng, [0, 0, 0], [2, 0, 0], [0, 2, 0.5], 4000)
    up = _up(plane)
    assert _angle(up.up, Z) < 1e-6 and up.axes is None and up.confidence == 0.0
    assert "no two perpendicular surfaces" in up.warning


def test_a_given_up_is_kept():
    given = np.array([0.0, 1.0, 0.0])
    means = voxel_groups(_room(), 0.05)[0]
    up = room_up(means, estimate_normals(means, 0.15), Z, given)
    assert up.source == "given" and _angle(up.up, given) < 1e-9 and up.confidence == 1.0

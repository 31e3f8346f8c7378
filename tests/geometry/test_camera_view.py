"""A room scan stored wherever its owner's frame put it keeps its floor: one lying above z = 0.1 m, seen from
an origin below or beside it, passes for a camera's view (:func:`cuboidcli.geometry.cloud.is_camera_view`),
and its file's own up then wins over the camera's -y when it scores a floor (:data:`OWN_FLOOR`)."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.geometry import cloud
from cuboidcli.geometry.cloud import OWN_FLOOR, floor_scores, is_camera_view, room_up

X, Y, Z = np.eye(3)


def shell(per_face: int = 400, seed: int = 3) -> tuple[np.ndarray, np.ndarray]:
    """A room 4 x 5 x 2.7 m around the origin (floor at z = 0): ``per_face`` points on each of its floor,
    ceiling and four walls, with their inward normals, and a table top 0.75 m high."""
    rng = np.random.default_rng(seed)
    lo, hi = np.array([-2.0, -2.5, 0.0]), np.array([2.0, 2.5, 2.7])
    pts, normals = [], []
    for axis in range(3):
        for side, value in ((1.0, lo[axis]), (-1.0, hi[axis])):
            p = rng.uniform(lo, hi, (per_face, 3))
            p[:, axis] = value
            pts.append(p)
            normals.append(np.tile(side * np.eye(3)[axis], (per_face, 1)))
    top = np.c_[rng.uniform(-0.6, 0.6, (per_face, 2)), np.full(per_face, 0.75)]
    return np.concatenate([*pts, top]), np.concatenate([*normals, np.tile(Z, (per_face, 1))])


@pytest.mark.parametrize("offset", [(0.0, 0.0, 0.5), (3.0, -2.0, 0.5), (-5.0, 0.0, 0.3)])
def test_a_room_stored_above_the_origin_keeps_its_floor_as_up(offset, monkeypatch):
    pts, normals = shell()
    pts = pts + np.array(offset)
    # seen from below or beside it, its 2800 points spread over so many rays that few hide each other
    assert pts[:, 2].min() > 0.1 and is_camera_view(pts)
    got = room_up(pts, normals, hint=Z)
    assert got.source == "estimated" and got.up @ Z > np.cos(np.deg2rad(1.0))
    monkeypatch.setattr(cloud, "OWN_FLOOR", 1.0)  # no floor would do: the camera's -y is up, on its side
    got = room_up(pts, normals, hint=Z)
    assert got.source == "camera" and abs(got.up @ Y) > np.cos(np.deg2rad(1.0))


def test_the_file_s_floor_wins_from_OWN_FLOOR_on(monkeypatch):
    pts, normals = shell()
    pts = pts + np.array([0.0, 0.0, 0.5])
    ok = np.linalg.norm(normals, axis=1) > 0.5
    score = floor_scores(pts[ok], normals[ok], np.eye(3))[4]  # +z: the floor of 400 of 2800 points
    assert score > OWN_FLOOR
    monkeypatch.setattr(cloud, "OWN_FLOOR", score)
    assert room_up(pts, normals, hint=Z).source == "estimated"
    monkeypatch.setattr(cloud, "OWN_FLOOR", np.nextafter(score, np.inf))
    assert room_up(pts, normals, hint=Z).source == "camera"


def test_a_camera_view_whose_file_up_scores_no_more_than_its_own_keeps_the_camera_s_up():
    # the same room kept in a camera's frame (y down, z forward, 1.4 m above the floor, 2.5 m from the back
    # wall): its floor lies along -y, and z finds only the wall behind the camera, which a view never sees
    pts, normals = shell()
    to_camera = np.array([X, -Z, Y])  # world x, y, z -> camera x, -z (y down), y (forward)
    pts = (pts - [0.0, -2.4, 1.4]) @ to_camera.T
    normals = normals @ to_camera.T
    seen = pts[:, 2] > 0.1
    got = room_up(pts[seen], normals[seen], hint=Z)
    assert got.source == "camera" and got.up @ -Y > np.cos(np.deg2rad(1.0))


def test_the_file_s_floor_must_outscore_the_camera_s():
    # the room above the origin with most of its floor unscanned (150 of 400 points): a floor enough for
    # OWN_FLOOR, but the wall at the far end of y (the camera's -y) scores more, and the camera's up stays;
    # the wall at the near end, as bare as the floor, scores less than either
    pts, normals = shell()
    keep = np.ones(len(pts), dtype=bool)
    keep[1750:2000] = False  # the floor's points are the fifth 400 (after four walls)
    keep[950:1200] = False  # and the wall at the near end of y (its +y) mostly unscanned too
    pts, normals = pts[keep] + np.array([0.0, 0.0, 0.5]), normals[keep]
    ok = np.linalg.norm(normals, axis=1) > 0.5
    scores = floor_scores(pts[ok], normals[ok], np.eye(3))
    assert scores[3] > scores[4] >= OWN_FLOOR > scores[2]  # -y above +z above +y
    assert room_up(pts, normals, hint=Z).source == "camera"


def test_a_sequence_s_cameras_are_never_second_guessed_as_one_camera_s_frame(monkeypatch):
    # the fused cloud of a sequence whose world frame puts the floor 0.5 m up passes for one camera's view;
    # its hint is its cameras' mean up, which no camera-frame guess replaces (even with no floor to tell)
    pts, normals = shell()
    pts = pts + np.array([3.0, -2.0, 0.5])
    monkeypatch.setattr(cloud, "OWN_FLOOR", 1.0)
    assert room_up(pts, normals, hint=Z).source == "camera"
    got = room_up(pts, normals, hint=Z, cameras=True)
    assert got.source == "estimated" and got.up @ Z > np.cos(np.deg2rad(1.0))

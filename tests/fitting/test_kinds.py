"""What each fitted box is: floor, wall, ceiling or object (fitting/shell.py cuboid_kind), decided once per
fit against gravity and the room-shell rule, written to the JSON and read back."""

from __future__ import annotations

import numpy as np
import pytest

import cuboidcli as cb
from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.shell import cuboid_kind


def test_the_rendered_room_gets_floor_walls_and_an_object(room_depth, nyu_camera):
    depth, _ = room_depth
    camera = cb.Camera(nyu_camera.fx, nyu_camera.fy, nyu_camera.cx, nyu_camera.cy)
    res = cb.fit(depth, camera, seed=0, hypotheses=256, max_cuboids=5, device="cpu")
    by_place = {}
    for c in res.cuboids:
        if abs(c.center[1] - 1.4) < 0.1:
            by_place["floor"] = c.kind
        elif abs(c.center[2] - 4.5) < 0.1 or abs(c.center[0] + 1.93) < 0.1:
            by_place.setdefault("walls", []).append(c.kind)
        elif np.linalg.norm(c.center - [-0.5, 1.1, 3.0]) < 0.15:
            by_place["box"] = c.kind
    assert by_place["floor"] == "floor" and by_place["box"] == "object"
    assert by_place["walls"] and set(by_place["walls"]) == {"wall"}
    kinds = [d["kind"] for d in res.to_json()["cuboids"]]
    assert kinds == [c.kind for c in res.cuboids]
    assert [c.name(i) for i, c in enumerate(res.cuboids)] == [f"{k}_{i:02d}" for i, k in enumerate(kinds)]


def test_level_slabs_above_the_camera_are_ceilings_and_tilted_ones_objects():
    down = np.array([0.0, 1.0, 0.0])
    rng = np.random.default_rng(0)
    # points of a room 4 x 2.6 x 5 m around the camera: every slab below is part of its shell
    pts = rng.uniform([-2.0, -1.2, 0.5], [2.0, 1.4, 5.0], (4000, 3))
    ceiling = Cuboid([0.0, -1.25, 2.5], [2.0, 0.03, 2.5], np.eye(3))
    floor = Cuboid([0.0, 1.45, 2.5], [2.0, 0.03, 2.5], np.eye(3))
    tilt = np.radians(45.0)
    ramp_rot = np.array([[1, 0, 0], [0, np.cos(tilt), -np.sin(tilt)], [0, np.sin(tilt), np.cos(tilt)]])
    ramp = Cuboid([0.0, 1.5, 5.1], [2.0, 0.03, 3.0], ramp_rot)
    assert cuboid_kind(pts, ceiling, down) == "ceiling"
    assert cuboid_kind(pts, floor, down) == "floor"
    assert cuboid_kind(pts, ramp, down) == "object"
    chunky = Cuboid([0.0, 1.0, 2.5], [0.4, 0.4, 0.4], np.eye(3))  # not a slab at all
    assert cuboid_kind(pts, chunky, down) == "object"


def test_old_results_without_kinds_read_as_objects_and_bad_kinds_are_refused():
    d = Cuboid([0, 0, 2], [0.1, 0.2, 0.3], np.eye(3), kind="wall").to_json(3)
    assert d["kind"] == "wall" and Cuboid.from_json(d).kind == "wall"
    del d["kind"]
    assert Cuboid.from_json(d).kind == "object" and "kind" not in Cuboid.from_json(d).extras
    with pytest.raises(ValueError, match="cuboid kind 'door'"):
        Cuboid.from_json({**d, "kind": "door"})

"""A room scanned from several poses (cuboidcli.synth.scan): poses, coverage, world-frame ground truth,
evaluation points and the "plain" sequence layout on disk."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.synth import materials
from cuboidcli.synth.room import SLAB
from cuboidcli.synth.scan import (
    generate_room_scan,
    object_boxes,
    read_scan_truth,
    truth_points,
    voxel_majority,
    write_room_scan,
)
from cuboidcli.synth.world import World, rot_z

SMALL = Camera.preset("nyu").scaled(0.25)  # 160x120
SEED = 4  # a closed room: four walls, no doorway


@pytest.fixture(scope="module")
def scan():
    return generate_room_scan(SEED, views=5, camera=SMALL)


def outside_distance(points: np.ndarray, box) -> np.ndarray:
    """Distance (N,) of points (N, 3) to an oriented box (0 inside), from the box's local coordinates."""
    local = (points - box.center) @ box.rotation
    return np.linalg.norm(np.maximum(np.abs(local) - box.half_size, 0.0), axis=1)


def world_points(scan, frame):
    """Exact depth of one view within the sensor's range, back-projected into the world: points (N, 3),
    instance ids (N,)."""
    keep = (frame.depth_clean_m >= 0.4) & (frame.depth_clean_m <= 10.0)
    cam = scan.camera.backproject(np.where(keep, frame.depth_clean_m, 0.0))[keep]
    pose = frame.world_from_camera
    return cam @ pose[:3, :3].T + pose[:3, 3], frame.instances[keep]


def test_the_scan_holds_views_of_one_room(scan):
    assert len(scan.frames) == 5 and scan.seed == [SEED] and scan.camera == SMALL
    assert scan.room["walls"] == [True] * 4 and scan.room["doorway"] is None
    for f in scan.frames:
        assert f.depth_m.shape == f.depth_clean_m.shape == f.instances.shape == (120, 160)
        assert f.rgb.shape == (120, 160, 3) and f.room == scan.room
    ids = [c.extras["object"] for c in scan.gt]
    assert ids == sorted(ids) and len(set(ids)) == len(ids)
    in_range = [f.instances[(f.depth_clean_m >= 0.4) & (f.depth_clean_m <= 10.0)] for f in scan.frames]
    seen = set().union(*(set(np.unique(i)) - {0} for i in in_range))
    assert set(ids) == seen  # one box per object the sensor could see in some view, none for others


def test_the_same_seed_gives_the_same_scan(scan):
    again = generate_room_scan(SEED, views=5, camera=SMALL)
    for a, b in zip(scan.frames, again.frames, strict=True):
        assert np.array_equal(a.depth_m, b.depth_m) and np.array_equal(a.rgb, b.rgb)
        assert np.array_equal(a.world_from_camera, b.world_from_camera)
    assert [c.to_json(0) for c in scan.gt] == [c.to_json(0) for c in again.gt]


def test_every_pose_stands_inside_the_room_and_the_yaws_go_round(scan):
    sx, sy, height = scan.room["size_m"]
    yaws = []
    for f in scan.frames:
        rot, pos = f.world_from_camera[:3, :3], f.world_from_camera[:3, 3]
        assert np.allclose(rot.T @ rot, np.eye(3)) and np.linalg.det(rot) == pytest.approx(1.0)
        assert 0.5 <= pos[0] <= sx - 0.5 and 0.5 <= pos[1] <= sy - 0.5 and 1.1 <= pos[2] <= 1.9 < height
        assert -np.sin(np.radians(21)) <= rot[2, 2] <= 1e-9  # slightly down, never up
        yaws.append(np.arctan2(rot[1, 2], rot[0, 2]))
    # five views looking across the room: their directions spread over the circle
    assert np.abs(np.exp(1j * np.array(yaws)).mean()) < 0.5


def test_the_views_together_see_the_floor_and_the_walls(scan):
    points, instance = truth_points(scan)
    per_object = np.bincount(instance, minlength=max(c.extras["object"] for c in scan.gt) + 1)
    floor = [c.extras["object"] for c in scan.gt if c.kind == "floor"]
    walls = [c.extras["object"] for c in scan.gt if c.kind == "wall"]
    assert len(floor) == 1 and per_object[floor[0]] > 0.05 * len(points)
    assert sum(per_object[w] > 0.02 * len(points) for w in walls) >= 3
    assert any(c.kind == "object" for c in scan.gt)


def test_shell_boxes_are_the_room_slabs(scan):
    sx, sy, height = scan.room["size_m"]
    by_kind = {k: [c for c in scan.gt if c.kind == k] for k in ("floor", "wall", "ceiling")}
    (floor,) = by_kind["floor"]
    assert floor.center[2] + floor.half_size[2] == pytest.approx(0.0, abs=1e-9)  # top face at z = 0
    assert 2 * floor.half_size[2] == pytest.approx(SLAB)
    assert floor.extras["category"] == "floor"
    for wall in by_kind["wall"]:
        z = wall.center[2] + np.array([-1, 1]) * wall.half_size[2]
        assert z == pytest.approx([0.0, height])
        assert abs(wall.rotation[2, 2]) == pytest.approx(1.0)  # upright
        # the inner face lies on the room's side: x = 0 or sx, or y = 0 or sy
        inner = wall.center[:2] + wall.rotation[:2, 1] * wall.half_size[1]
        assert min(abs(inner[0]), abs(inner[0] - sx), abs(inner[1]), abs(inner[1] - sy)) < 1e-9
    for ceiling in by_kind["ceiling"]:
        assert ceiling.center[2] - ceiling.half_size[2] == pytest.approx(height)


def test_every_seen_point_lies_in_its_objects_box(scan):
    boxes = {c.extras["object"]: c for c in scan.gt}
    for frame in scan.frames[:2]:
        points, instance = world_points(scan, frame)
        for oid in np.unique(instance):
            d = outside_distance(points[instance == oid], boxes[oid])
            assert d.max() <= 0.02, (oid, boxes[oid].extras, d.max())
            if boxes[oid].kind != "object":  # a slab is seen on its face: on the box's surface
                local = np.abs((points[instance == oid] - boxes[oid].center) @ boxes[oid].rotation)
                assert np.abs(local - boxes[oid].half_size).min(axis=1).max() < 1e-3
    points, instance = truth_points(scan)
    assert points.dtype == np.float32 and instance.dtype == np.int32 and instance.min() > 0
    for oid in np.unique(instance):
        assert outside_distance(points[instance == oid].astype(float), boxes[oid]).max() <= 0.02


def test_object_boxes_are_tight_and_turned_to_the_objects_yaw():
    world = World()
    mat = world.add_material(materials.sample("wall", np.random.default_rng(0)))
    oid = world.new_object("table")
    rot = rot_z(0.3)
    # a top 1.0 x 0.6 x 0.04 at 0.74-0.78 m and one leg 0.05 x 0.05 x 0.74 under a corner (object frame)
    origin = np.array([2.0, 1.0, 0.0])
    world.add_box(oid, "top", origin + rot @ [0.0, 0.0, 0.76], [0.5, 0.3, 0.02], rot, mat)
    world.add_box(oid, "leg", origin + rot @ [0.45, 0.25, 0.37], [0.025, 0.025, 0.37], rot, mat)
    fid = world.new_object("floor")
    world.add_box(fid, "slab", [1.0, 1.0, -0.025], [3.0, 2.0, 0.025], np.eye(3), mat)
    boxes = object_boxes(world)
    table, floor = boxes[oid], boxes[fid]
    assert table.kind == "object" and floor.kind == "floor"
    assert table.extras == {"object": oid, "category": "table"}
    assert np.allclose(table.rotation, rot)
    assert np.allclose(table.half_size, [0.5, 0.3, 0.39])
    assert np.allclose(table.center, origin + rot @ [0.0, 0.0, 0.39])
    assert np.allclose(floor.center, [1.0, 1.0, -0.025]) and np.allclose(floor.half_size, [3.0, 2.0, 0.025])


def test_voxel_majority_keeps_the_majority_label_and_its_mean():
    points = np.array(
        [
            [0.001, 0.001, 0.001],  # voxel (0, 0, 0): labels 5, 5, 7 -> 5
            [0.003, 0.001, 0.001],
            [0.009, 0.009, 0.009],
            [0.015, 0.001, 0.001],  # voxel (1, 0, 0): a tie 9 / 3 -> 3
            [0.019, 0.005, 0.001],
        ]
    )
    labels = np.array([5, 5, 7, 9, 3])
    out, ids = voxel_majority(points, labels, 0.01)
    assert ids.tolist() == [5, 3]
    assert np.allclose(out, [[0.002, 0.001, 0.001], [0.019, 0.005, 0.001]], atol=1e-7)
    assert voxel_majority(np.zeros((0, 3)), np.zeros(0), 0.01)[0].shape == (0, 3)


def test_write_and_read_round_trip(scan, tmp_path):
    import cv2

    root = write_room_scan(tmp_path / "room", scan)
    cameras = json.loads((root / "cameras.json").read_text())
    assert cameras == {
        "fx": SMALL.fx,
        "fy": SMALL.fy,
        "cx": SMALL.cx,
        "cy": SMALL.cy,
        "width": 160,
        "height": 120,
        "depth_scale": 0.001,
    }
    for k, f in enumerate(scan.frames):
        name = f"{k:06d}"
        depth = cv2.imread(str(root / "depth" / f"{name}.png"), cv2.IMREAD_UNCHANGED)
        assert depth.dtype == np.uint16 and np.array_equal(depth, np.rint(f.depth_m * 1000).astype(np.uint16))
        color = cv2.imread(str(root / "color" / f"{name}.png"), cv2.IMREAD_COLOR)
        assert np.array_equal(color[..., ::-1], f.rgb)
        inst = cv2.imread(str(root / "instances" / f"{name}.png"), cv2.IMREAD_UNCHANGED)
        assert inst.dtype == np.uint16 and np.array_equal(inst, f.instances)
        pose = np.loadtxt(root / "pose" / f"{name}.txt")
        assert pose.shape == (4, 4) and np.allclose(pose, f.world_from_camera, rtol=0, atol=1e-10)
    doc = json.loads((root / "gt.json").read_text())
    assert doc["schema"] == "cuboids/1" and doc["frame"] == "world" and doc["room"] == scan.room
    assert {o["id"] for o in doc["objects"]} == {c.extras["object"] for c in scan.gt}
    gt, points, instance = read_scan_truth(root)
    assert [c.kind for c in gt] == [c.kind for c in scan.gt]
    for a, b in zip(gt, scan.gt, strict=True):
        assert np.allclose(a.center, b.center) and np.allclose(a.half_size, b.half_size)
        assert np.allclose(a.rotation, b.rotation) and a.extras["object"] == b.extras["object"]
    expected_points, expected_instance = truth_points(scan)
    assert np.array_equal(points, expected_points) and np.array_equal(instance, expected_instance)

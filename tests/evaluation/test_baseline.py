"""The Open3D baseline (cuboidcli.evaluation.baseline): planes become shell slabs, clusters upright boxes."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.baseline import min_area_rectangle, planes_and_clusters
from cuboidcli.evaluation.iou import box_iou

SIDES_AND_TOP = [(0, -1), (0, 1), (1, -1), (1, 1), (2, 1)]


def rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def sample_faces(box: Cuboid, faces, rng, per_m2: float = 3000.0) -> np.ndarray:
    """Uniform random points on the given faces (axis, sign) of a box, ``per_m2`` per square metre."""
    out = []
    for axis, sign in faces:
        a, b = [k for k in range(3) if k != axis]
        n = int(4 * box.half_size[a] * box.half_size[b] * per_m2)
        local = np.zeros((n, 3))
        local[:, axis] = sign * box.half_size[axis]
        local[:, a] = rng.uniform(-1, 1, n) * box.half_size[a]
        local[:, b] = rng.uniform(-1, 1, n) * box.half_size[b]
        out.append(local @ box.rotation.T + box.center)
    return np.concatenate(out)


ROOM = [
    Cuboid([2.0, 2.0, -0.025], [2.0, 2.0, 0.025], np.eye(3), kind="floor"),
    Cuboid([2.0, -0.025, 1.25], [2.0, 0.025, 1.25], np.eye(3), kind="wall"),
    Cuboid([-0.025, 2.0, 1.25], [0.025, 2.0, 1.25], np.eye(3), kind="wall"),
    Cuboid([2.5, 2.5, 0.35], [0.4, 0.25, 0.35], rot_z(0.5)),
    Cuboid([1.2, 2.9, 0.5], [0.2, 0.2, 0.5], np.eye(3)),
]
VISIBLE = [[(2, 1)], [(1, 1)], [(0, 1)], SIDES_AND_TOP, SIDES_AND_TOP]


@pytest.fixture(scope="module")
def cloud() -> np.ndarray:
    """The visible surfaces of ROOM with 3 mm of noise: (N, 3)."""
    rng = np.random.default_rng(0)
    points = np.concatenate([sample_faces(b, f, rng) for b, f in zip(ROOM, VISIBLE, strict=True)])
    return points + rng.normal(0.0, 0.003, points.shape)


def best_iou(box: Cuboid, candidates: list[Cuboid]) -> float:
    return max(box_iou(box, c) for c in candidates)


def test_a_floor_two_walls_and_two_objects(cloud):
    boxes = planes_and_clusters(cloud)
    kinds = [b.kind for b in boxes]
    assert sorted(kinds[:3]) == ["floor", "wall", "wall"] and kinds[3:] == ["object", "object"]
    for truth in ROOM:
        same_kind = [b for b in boxes if b.kind == truth.kind]
        # slabs: the face on the plane, 5 cm thick behind it; objects: the footprint and height
        assert best_iou(truth, same_kind) > 0.85, truth
    (floor,) = [b for b in boxes if b.kind == "floor"]
    assert floor.center[2] + floor.half_size[2] == pytest.approx(0.0, abs=0.005)
    for b in boxes:
        assert np.allclose(b.rotation.T @ b.rotation, np.eye(3)) and np.linalg.det(b.rotation) > 0


def test_the_same_cloud_gives_the_same_boxes(cloud):
    a, b = planes_and_clusters(cloud, seed=3), planes_and_clusters(cloud, seed=3)
    assert [x.kind for x in a] == [x.kind for x in b]
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x.center, y.center) and np.array_equal(x.half_size, y.half_size)


def test_any_up_direction(cloud):
    # the same room turned over: its up is now along a tilted axis, and the boxes turn with it
    c, s = math.cos(0.7), math.sin(0.7)
    turn = np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]]) @ rot_z(0.3)
    boxes = planes_and_clusters(cloud @ turn.T, up=turn[:, 2])
    assert sorted(b.kind for b in boxes) == ["floor", "object", "object", "wall", "wall"]
    for truth in ROOM:
        turned = Cuboid(turn @ truth.center, truth.half_size, turn @ truth.rotation)
        assert best_iou(turned, [b for b in boxes if b.kind == truth.kind]) > 0.85


def test_a_table_top_is_not_a_floor():
    rng = np.random.default_rng(1)
    floor = Cuboid([2.0, 2.0, -0.025], [2.0, 2.0, 0.025], np.eye(3), kind="floor")
    table = Cuboid([2.0, 2.0, 0.73], [1.0, 0.75, 0.02], rot_z(0.2))  # a large top: 3 m^2 at 0.75 m
    points = np.concatenate([sample_faces(floor, [(2, 1)], rng), sample_faces(table, SIDES_AND_TOP, rng)])
    boxes = planes_and_clusters(points)
    assert [b.kind for b in boxes].count("floor") == 1 and "ceiling" not in [b.kind for b in boxes]
    objects = [b for b in boxes if b.kind == "object"]
    assert len(objects) == 1 and box_iou(objects[0], table) > 0.5


def test_too_few_points_give_no_boxes():
    assert planes_and_clusters(np.zeros((0, 3))) == []
    assert planes_and_clusters(np.array([[0.0, 0.0, 0.0], [1.0, 0.0, 0.0]])) == []


def test_the_min_area_rectangle_of_a_turned_rectangle():
    rng = np.random.default_rng(2)
    angle = math.radians(30.0)
    axes = np.array([[math.cos(angle), math.sin(angle)], [-math.sin(angle), math.cos(angle)]])
    local = np.concatenate(
        [[[-1.0, -0.5], [1.0, -0.5], [1.0, 0.5], [-1.0, 0.5]], rng.uniform(-0.5, 0.5, (50, 2))]
    )
    xy = local @ axes + [3.0, -1.0]
    centre, half, found = min_area_rectangle(xy)
    assert centre == pytest.approx([3.0, -1.0]) and half == pytest.approx([1.0, 0.5])
    assert found == pytest.approx(angle)
    # its principal axes would not do: an L-shape's smallest rectangle is axis-aligned
    ell = np.array([[0.0, 0.0], [3.0, 0.0], [3.0, 0.2], [0.2, 0.2], [0.2, 3.0], [0.0, 3.0]])
    centre, half, found = min_area_rectangle(ell)
    assert 4 * half.prod() == pytest.approx(9.0) and found == pytest.approx(0.0)


def test_on_a_synthetic_room_scan():
    from cuboidcli.camera import Camera
    from cuboidcli.evaluation.scene import scene_metrics
    from cuboidcli.synth.scan import generate_room_scan, truth_points

    camera = Camera.preset("nyu").scaled(0.25)
    scan = generate_room_scan(4, views=4, camera=camera)  # a closed room with four walls
    fused = []
    for f in scan.frames:  # the sensor's depth, noise and holes included, as a user has it
        valid = f.depth_m > 0
        points = camera.backproject(np.where(valid, f.depth_m, 0.0))[valid]
        fused.append(points @ f.world_from_camera[:3, :3].T + f.world_from_camera[:3, 3])
    boxes = planes_and_clusters(np.concatenate(fused))
    kinds = [b.kind for b in boxes]
    assert kinds.count("floor") == 1 and kinds.count("wall") >= 2 and "object" in kinds
    m = scene_metrics(boxes, scan.gt, *truth_points(scan))
    assert m["shell_box_precision_iou0.5_pct"] == 100.0  # every slab lies on a wall or the floor
    assert m["auc20cm_pct"] > 70.0

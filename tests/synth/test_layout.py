"""Furnishing a room (cuboidcli.synth.layout) and free-space bookkeeping (cuboidcli.synth.placement):
where furniture, small objects and clutter end up in a world built by ``scene.build_world``."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.iou import intersection_volume
from cuboidcli.synth.furniture import FLOOR_FURNITURE
from cuboidcli.synth.layout import CAMERA_CLEARANCE_M
from cuboidcli.synth.placement import Occupancy, Pose, upright_boxes
from cuboidcli.synth.scene import SceneOptions, build_world
from cuboidcli.synth.view import STRUCTURE
from cuboidcli.synth.world import MESH, rot_z
from tests.synth.helpers import corners

SEEDS = range(12)
#: Floor furniture proper; "box" stands on the floor or, as a small object, on a surface.
ON_THE_FLOOR = set(FLOOR_FURNITURE) - {"box"}


def _world(seed: int):
    world, position = build_world(np.random.default_rng(seed), SceneOptions())
    return world, position


def _solids(world):
    """Every non-structural solid as (object id, category, Cuboid): box parts as they are, clutter meshes
    as their bounding box in the object's own (upright) frame, which is what placement reserves."""
    solids = []
    for p in world.parts:
        obj = world.object(p.object_id)
        if obj.category not in STRUCTURE:
            solids.append((obj.id, obj.category, Cuboid(p.center, p.half_size, p.rotation)))
    for m in world.meshes:
        rotation, origin = m.frame
        local = (m.vertices - origin) @ rotation
        lo, hi = local.min(0), local.max(0)
        center = origin + rotation @ ((lo + hi) / 2)
        solids.append(
            (m.object_id, world.object(m.object_id).category, Cuboid(center, (hi - lo) / 2, rotation))
        )
    return solids


def _bottom_and_footprint(world, oid: int):
    pts = [corners(p.center, p.half_size, p.rotation) for p in world.parts if p.object_id == oid]
    pts += [m.vertices for m in world.meshes if m.object_id == oid]
    pts = np.concatenate(pts)
    return pts[:, 2].min(), pts[:, :2]


def test_furniture_stands_on_the_floor_and_small_objects_on_a_support():
    counts = {"floor": 0, "supported": 0, "wall_cupboard": 0}
    for seed in SEEDS:
        world, _ = _world(seed)
        for obj in world.objects:
            if obj.category in STRUCTURE:
                continue
            bottom, footprint = _bottom_and_footprint(world, obj.id)
            if obj.category in ON_THE_FLOOR:
                assert bottom == pytest.approx(0.0, abs=1e-9), (seed, obj)
                counts["floor"] += 1
            elif obj.category == "wall_cupboard":
                assert 1.4 - 1e-9 <= bottom <= 1.7 + 1e-9
                counts["wall_cupboard"] += 1
            elif abs(bottom) > 1e-9:
                # standing fully on the top face of a part of another object
                supports = [
                    p
                    for p in world.parts
                    if p.object_id != obj.id
                    and abs(p.center[2] + p.half_size[2] - bottom) < 1e-9
                    and np.all(
                        np.abs((footprint - p.center[:2]) @ p.rotation[:2, :2]) <= p.half_size[:2] + 1e-9
                    )
                ]
                assert supports, (seed, obj)
                counts["supported"] += 1
    assert min(counts.values()) > 0, counts


def test_nothing_overlaps_leaves_the_room_or_blocks_the_camera():
    for seed in SEEDS:
        world, position = _world(seed)
        sx, sy, h = world.room["size_m"]
        solids = _solids(world)
        assert len(solids) > 5
        camera_zone = Cuboid([*position[:2], h / 2], [CAMERA_CLEARANCE_M, CAMERA_CLEARANCE_M, h], np.eye(3))
        for _, category, box in solids:
            c = box.corners()
            assert c[:, :2].min() >= -1e-9 and c[:, 0].max() <= sx + 1e-9 and c[:, 1].max() <= sy + 1e-9
            assert c[:, 2].min() >= -1e-9, (seed, category)
            assert c[:, 2].max() <= h + 1e-9, (seed, category)  # below the ceiling
            assert intersection_volume(box, camera_zone) < 1e-9, (seed, category)
        for i, (oid_a, cat_a, a) in enumerate(solids):
            for oid_b, cat_b, b in solids[i + 1 :]:
                if oid_a == oid_b or np.linalg.norm(a.center - b.center) > np.linalg.norm(
                    a.half_size
                ) + np.linalg.norm(b.half_size):
                    continue
                # touching (a chair against a table, a book on a shelf board) is fine, overlapping is not
                assert intersection_volume(a, b) < 1e-9, (seed, cat_a, cat_b)


def test_wall_cupboards_stay_below_the_ceiling():
    """A wall cupboard's bottom (1.4-1.7 m) plus its height (0.5-0.8 m) reaches 2.5 m while rooms are
    2.4-3.1 m high: the worlds of these seeds drew one that would cut into the ceiling slab."""
    cupboards = 0
    for seed in (831, 888, 1241, *range(800, 830)):
        world, _ = _world(seed)
        tops = [
            corners(p.center, p.half_size, p.rotation)[:, 2].max()
            for p in world.parts
            if world.object(p.object_id).category == "wall_cupboard"
        ]
        cupboards += len(tops)
        assert max(tops, default=0.0) <= world.room["size_m"][2] + 1e-9, seed
    assert cupboards >= 5  # the check saw cupboards, not worlds without any


def test_furniture_parts_are_upright_and_the_camera_stands_inside_the_room():
    for seed in SEEDS:
        world, position = _world(seed)
        sx, sy, h = world.room["size_m"]
        assert 0.7 - 1e-9 <= position[0] <= sx - 0.7 + 1e-9 and 0.7 - 1e-9 <= position[1] <= sy - 0.7 + 1e-9
        assert 1.2 <= position[2] <= 1.8
        for p in world.parts:  # yaw only: the z axis stays vertical
            assert np.allclose(p.rotation[:, 2], [0.0, 0.0, 1.0]) and np.allclose(
                p.rotation[2], [0.0, 0.0, 1.0]
            )
        for m in world.meshes:
            assert world.object(m.object_id).kind == MESH
        # one to three lights under the ceiling, inside the room
        assert 1 <= len(world.lights) <= 3
        for light, power in world.lights:
            assert 0 < light[0] < sx and 0 < light[1] < sy and h - 0.4 - 1e-9 <= light[2] <= h - 0.05 + 1e-9
            assert power > 0


def test_occupancy_lets_boxes_touch_but_not_overlap():
    occ = Occupancy()
    assert not occ.collides([0.0, 0.0], 0.0, [1.0, 1.0], [0.0, 1.0])  # nothing placed yet
    occ.add([0.0, 0.0], 0.0, [0.5, 0.5], [0.0, 1.0])
    assert len(occ) == 1
    # flush against a side, stacked on top, or just beyond: free
    assert not occ.collides([1.0, 0.0], 0.0, [0.5, 0.5], [0.0, 1.0])
    assert not occ.collides([0.0, 0.0], 0.0, [0.5, 0.5], [1.0, 2.0])
    assert not occ.collides([0.0, 1.01], 0.0, [0.5, 0.5], [0.5, 0.7])
    # a millimetre of overlap in the plane and in height: taken
    assert occ.collides([0.999, 0.0], 0.0, [0.5, 0.5], [0.0, 1.0])
    assert occ.collides([0.0, 0.0], 0.0, [0.5, 0.5], [0.999, 2.0])
    # a square turned by 45 degrees reaches sqrt(2) / 2 from its centre along x (the separating-axis test
    # must use the turned box's own axes, not just the placed one's)
    reach = 0.5 + 0.5 * np.sqrt(2.0)
    assert occ.collides([reach - 0.01, 0.0], np.pi / 4, [0.5, 0.5], [0.0, 1.0])
    assert not occ.collides([reach + 0.01, 0.0], np.pi / 4, [0.5, 0.5], [0.0, 1.0])
    # diagonally off the placed square's corner, the turned square's side faces that corner: only the
    # turned square's own axes separate the two (their shadows on x and y overlap either way)
    assert not occ.collides([0.51 + np.sqrt(0.125), 0.51 + np.sqrt(0.125)], np.pi / 4, [0.5, 0.5], [0.0, 1.0])
    assert occ.collides([0.49 + np.sqrt(0.125), 0.49 + np.sqrt(0.125)], np.pi / 4, [0.5, 0.5], [0.0, 1.0])
    # several candidates at once: any one colliding counts
    both = np.array([[5.0, 5.0], [0.2, 0.2]])
    assert occ.collides(both, [0.0, 0.0], [[0.1, 0.1], [0.1, 0.1]], [[0.0, 1.0], [0.0, 1.0]])
    assert not occ.collides(both[:1], [0.0], [[0.1, 0.1]], [[0.0, 1.0]])


def test_pose_and_upright_boxes():
    pose = Pose(np.array([2.0, 1.0]), 0.75, np.pi / 2)
    assert np.allclose(pose.rotation, rot_z(np.pi / 2))
    # object x points along world y after a quarter turn; the origin goes to (2, 1, 0.75)
    assert np.allclose(pose.apply([[1.0, 0.0, 0.0], [0.0, 0.0, 0.0]]), [[2.0, 2.0, 0.75], [2.0, 1.0, 0.75]])
    center, yaw, half, z = upright_boxes(pose, np.array([[-1.0, -0.5, 0.0]]), np.array([[1.0, 0.5, 0.3]]))
    assert np.allclose(center, [[2.0, 1.0]]) and np.allclose(yaw, [np.pi / 2])
    assert np.allclose(half, [[1.0, 0.5]]) and np.allclose(z, [[0.75, 1.05]])

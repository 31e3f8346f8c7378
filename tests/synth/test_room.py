"""cuboidcli.synth.room: the room's structure, checked with an independent ray caster (helpers.py)."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.synth import SceneOptions, generate_scene
from cuboidcli.synth.placement import Occupancy
from cuboidcli.synth.room import SLAB, build_room
from cuboidcli.synth.world import World
from tests.synth.helpers import cast_boxes, corners, sphere_directions

SEEDS = range(16)  # 4-wall rooms, rooms with missing walls, doorways with and without a frame
TINY = Camera.preset("nyu").scaled(0.2)  # 128x96


def _room(seed: int):
    world = World()
    room = build_room(world, Occupancy(), np.random.default_rng(seed))
    return world, room


def _exits(room, origin: np.ndarray, dirs: np.ndarray):
    """Where rays from ``origin`` leave the interior box: distance (N,), face (N,) (0-3: wall side k as in
    room.sides, 4: floor, 5: ceiling) and the exit point (N, 3)."""
    sx, sy, h = room.size
    with np.errstate(divide="ignore"):
        tx = np.where(dirs[:, 0] > 0, (sx - origin[0]) / dirs[:, 0], -origin[0] / dirs[:, 0])
        ty = np.where(dirs[:, 1] > 0, (sy - origin[1]) / dirs[:, 1], -origin[1] / dirs[:, 1])
        tz = np.where(dirs[:, 2] > 0, (h - origin[2]) / dirs[:, 2], -origin[2] / dirs[:, 2])
    t = np.stack([np.abs(tx), np.abs(ty), np.abs(tz)], 1)
    axis = t.argmin(1)
    face = np.select(
        [
            (axis == 1) & (dirs[:, 1] < 0),
            (axis == 0) & (dirs[:, 0] > 0),
            axis == 1,
            axis == 0,
            dirs[:, 2] < 0,
        ],
        [0, 1, 2, 3, 4],
        5,
    )
    dist = t.min(1)
    return dist, face, origin + dist[:, None] * dirs


def _wall_coordinates(side, points: np.ndarray):
    """(a, b) of world points (N, 3) in a wall side's frame: along the wall, and into the room."""
    d = points[:, :2] - side.origin
    return d @ side.tangent, d @ side.normal


def test_rooms_have_the_documented_structure():
    kinds = set()
    for seed in SEEDS:
        world, room = _room(seed)
        sx, sy, h = room.size
        assert 3.0 <= sx <= 7.0 and 3.0 <= sy <= 7.0 and 2.4 <= h <= 3.1
        assert sum(s.present for s in room.sides) >= 2
        doors = [s for s in room.sides if s.doorway is not None]
        assert len(doors) <= 1 and all(s.present for s in doors)
        kinds.add((all(s.present for s in room.sides), bool(doors)))
        for side in room.sides:  # right-handed wall frames: normal = z x tangent, pointing inwards
            assert side.normal @ side.tangent == 0
            assert side.tangent[0] * side.normal[1] - side.tangent[1] * side.normal[0] == 1
            inward = side.to_world(side.length / 2, 0.1)
            assert 0 < inward[0] < sx and 0 < inward[1] < sy
        for p in world.parts:
            box = corners(p.center, p.half_size, p.rotation)
            category = world.object(p.object_id).category
            if category != "door_frame":  # floors, ceilings and walls are slabs
                assert p.half_size.min() == pytest.approx(SLAB / 2)
            if category == "floor":  # the floor slab hangs below z = 0, its top is the floor
                assert box[:, 2].max() == pytest.approx(0.0, abs=1e-12)
                assert box[:, 2].min() == pytest.approx(-SLAB, abs=1e-12)
            elif category == "ceiling":
                assert box[:, 2].min() == pytest.approx(h, abs=1e-12)
            elif p.name == "slab":  # wall slabs (beside a doorway too) run from the floor to the ceiling
                assert box[:, 2].min() == pytest.approx(0.0, abs=1e-12)
                assert box[:, 2].max() == pytest.approx(h, abs=1e-12)
            else:  # the lintel above a doorway, the door frame's jambs and head
                assert p.name in ("lintel", "jamb", "head")
                assert box[:, 2].min() >= -1e-12 and box[:, 2].max() <= h + 1e-12
        # each standing wall runs over the (main) floor's whole extent along it, into the neighbouring
        # walls at the corners and on into the hall beside a missing wall
        floor = world.parts[0]
        assert world.object(floor.object_id).category == "floor"
        for side in room.sides:
            if not side.present:
                continue
            along, _ = _wall_coordinates(side, corners(floor.center, floor.half_size, floor.rotation))
            in_wall = []
            for p in world.parts:
                a, b = _wall_coordinates(side, corners(p.center, p.half_size, p.rotation))
                if world.object(p.object_id).category == "wall" and b.min() > -SLAB - 1e-9 and b.max() < 1e-9:
                    in_wall.append(a)
            in_wall = np.concatenate(in_wall)
            assert in_wall.min() == pytest.approx(along.min()) and in_wall.max() == pytest.approx(along.max())
            assert along.max() - along.min() >= side.length + 2 * SLAB - 1e-9
    assert kinds == {(True, True), (True, False), (False, True), (False, False)}


@pytest.mark.parametrize("seed", SEEDS)
def test_walls_floor_and_ceiling_close_the_room_where_walls_stand(seed):
    """Every ray from inside leaves the room's interior box exactly on a structural surface, except through
    a missing wall (the floor and ceiling continue there) and through the doorway."""
    world, room = _room(seed)
    boxes = [(p.center, p.half_size, p.rotation) for p in world.parts]
    dirs = sphere_directions(4000)
    rng = np.random.default_rng(seed)
    for _ in range(3):
        origin = rng.uniform([0.3, 0.3, 0.3], room.size - 0.3)
        t, _ = cast_boxes(origin, dirs, boxes)
        exit_t, face, exit_point = _exits(room, origin, dirs)
        closed = np.ones(len(dirs), bool)
        for k, side in enumerate(room.sides):
            if not side.present:
                closed &= face != k
            elif side.doorway is not None:
                # the opening, and the door frame standing out into the room around it
                a0, a1, _ = side.doorway
                a, b = _wall_coordinates(side, exit_point)
                closed &= ~((a > a0 - 0.2) & (a < a1 + 0.2) & (b < 0.1))
        assert closed.sum() > 1000
        assert np.allclose(t[closed], exit_t[closed], rtol=0, atol=1e-9)
        # a missing wall opens the room into a hall: nothing stands in the opening, and the floor and
        # ceiling go on 6-12 m beyond it
        for k, side in enumerate(room.sides):
            if side.present:
                continue
            out = face == k
            assert out.any() and (t[out] > exit_t[out]).all()
            t_plane = np.where(dirs[:, 2] < 0, -origin[2], room.size[2] - origin[2]) / dirs[:, 2]
            a, b = _wall_coordinates(side, origin + t_plane[:, None] * dirs)
            in_hall = out & (b < 0) & (b > -5.9) & (a > 0) & (a < side.length)
            assert in_hall.sum() > 20
            assert np.allclose(t[in_hall], t_plane[in_hall], rtol=0, atol=1e-9)


def test_the_doorway_leads_somewhere_and_is_kept_free():
    seen = 0
    for seed in SEEDS:
        world = World()
        occ = Occupancy()
        room = build_room(world, occ, np.random.default_rng(seed))
        door = next((k for k, s in enumerate(room.sides) if s.doorway is not None), None)
        if door is None:
            assert len(occ) == 0
            continue
        seen += 1
        side = room.sides[door]
        a0, a1, door_h = side.doorway
        assert 0.8 <= a1 - a0 <= 1.6 and 2.0 <= door_h <= room.size[2] - 0.15 + 1e-12
        # a horizontal ray through the middle of the opening passes the wall plane
        origin = np.append(side.to_world((a0 + a1) / 2, 0.5), door_h / 2)
        direction = np.append(-side.normal, 0.0)
        t, _ = cast_boxes(origin, direction[None], [(p.center, p.half_size, p.rotation) for p in world.parts])
        assert t[0] > 0.5 + SLAB
        # the space in front of the doorway (0.9 m deep, as wide and high as the opening) is reserved
        assert len(occ) == 1
        inside = np.append(side.to_world((a0 + a1) / 2, 0.45), 1.0)
        assert occ.collides(inside[:2], 0.0, [0.01, 0.01], [0.5, 0.6])
        assert list(occ.half[0]) == pytest.approx([(a1 - a0) / 2, 0.45])
        assert list(occ.z[0]) == pytest.approx([0.0, door_h])
    assert seen >= 3


@pytest.mark.parametrize("seed, pitch", [(0, (-30.0, -20.0)), (3, (-30.0, -20.0)), (5, (5.0, 10.0))])
def test_the_floor_lies_the_configured_camera_height_below_the_camera(seed, pitch):
    height = 1.37
    scene = generate_scene(seed, TINY, SceneOptions(camera_height_m=(height, height), pitch_deg=pitch))
    assert scene.world_from_camera[2, 3] == pytest.approx(height)
    up = scene.world_from_camera[:3, :3].T @ [0.0, 0.0, 1.0]  # the world's up in the camera frame
    # the floor slab's top face and the ceiling slab's bottom face, relative to the camera
    planes = {"floor": -height, "ceiling": scene.room["size_m"][2] - height}
    seen = 0
    for category, level in planes.items():
        for c in (c for c in scene.cuboids if c.extras["category"] == category):
            heights = corners(c.center, c.half_size, c.rotation) @ up
            surface, back = (
                (heights.max(), heights.min()) if category == "floor" else (heights.min(), heights.max())
            )
            assert surface == pytest.approx(level, abs=1e-9) and abs(back - surface) == pytest.approx(SLAB)
        # and so do the pixels of the exact depth map that see them
        ids = [o["id"] for o in scene.objects if o["category"] == category]
        points = scene.camera.backproject(scene.depth_clean_m)[np.isin(scene.instances, ids)]
        if len(points):
            assert np.abs(points @ up - level).max() < 1e-4
        seen += len(points)
    assert seen > 1000

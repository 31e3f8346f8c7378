"""Furnishing a room: furniture against walls, free-standing or touching other pieces, small objects on
surfaces, clutter on the floor, lights under the ceiling. World frame, metres, z up."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cuboidcli.synth import materials
from cuboidcli.synth.clutter import FLOOR_CLUTTER, SMALL_CLUTTER, MeshAssembly, pipe
from cuboidcli.synth.furniture import FLOOR_FURNITURE, SMALL_OBJECTS, Assembly, Surface, wall_cupboard
from cuboidcli.synth.placement import Occupancy, Pose, upright_boxes
from cuboidcli.synth.room import Room
from cuboidcli.synth.world import MESH, World

CAMERA_CLEARANCE_M = 0.45
"""Half-size of the square around the camera position kept free of objects (all heights)."""


@dataclass
class Placed:
    """A placed floor-standing object: its assembly, pose and object id (for touching placements)."""

    assembly: Assembly
    pose: Pose
    object_id: int


def _pick(table: dict, rng: np.random.Generator) -> str:
    names = list(table)
    weights = np.array([table[n][1] for n in names], float)
    return names[int(rng.choice(len(names), p=weights / weights.sum()))]


def _materials_for(world: World, category: str, roles, rng: np.random.Generator) -> dict[str, int]:
    return {
        r: world.add_material(materials.sample(materials.palette_for(category, r, rng), rng))
        for r in sorted(set(roles))
    }


def _inside_room(room: Room, pose: Pose, lo: np.ndarray, hi: np.ndarray) -> bool:
    """Whether the piece's footprint lies inside the room and its top below the ceiling (a tall wall
    cupboard in a low room would cut into the ceiling slab)."""
    corners = np.array([[x, y, 0.0] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])])
    xy = pose.apply(corners)[:, :2]
    inside = (xy >= -1e-9).all() and (xy <= room.size[:2] + 1e-9).all()
    return bool(inside and pose.z + hi[2] <= room.size[2] + 1e-9)


def place_assembly(
    world: World, occ: Occupancy, room: Room, asm: Assembly, pose: Pose, rng: np.random.Generator
) -> int | None:
    """Add a box assembly's parts at ``pose`` if they fit inside the room and collide with nothing placed;
    returns the new object id, or None (nothing added)."""
    lo, hi = asm.bounds()
    if not _inside_room(room, pose, lo, hi):
        return None
    boxes = upright_boxes(pose, np.array([p.lo for p in asm.parts]), np.array([p.hi for p in asm.parts]))
    if occ.collides(*boxes):
        return None
    occ.add(*boxes)
    oid = world.new_object(asm.category)
    mats = _materials_for(world, asm.category, [p.role for p in asm.parts], rng)
    rot = pose.rotation
    for p in asm.parts:
        world.add_box(oid, p.name, pose.apply((p.lo + p.hi) / 2), (p.hi - p.lo) / 2, rot, mats[p.role])
    return oid


def _wall_pose(room: Room, asm: Assembly, rng: np.random.Generator) -> Pose | None:
    """Back of the piece flush against (or 0-5 cm off) a random wall, facing into the room."""
    sides = [s for s in room.sides if s.present]
    side = sides[
        int(rng.choice(len(sides), p=np.array([s.length for s in sides]) / sum(s.length for s in sides)))
    ]
    lo, hi = asm.bounds()
    width = hi[0] - lo[0]
    if width > side.length:
        return None
    a = rng.uniform(-lo[0], side.length - hi[0])
    b = -lo[1] + (0.0 if rng.random() < 0.6 else rng.uniform(0.0, 0.05))
    return Pose(side.to_world(a, b), 0.0, side.yaw)


def _free_pose(room: Room, asm: Assembly, rng: np.random.Generator) -> Pose:
    lo, hi = asm.bounds()
    r = float(np.hypot(*np.maximum(np.abs(lo[:2]), np.abs(hi[:2]))))
    xy = rng.uniform(0, 1, 2) * np.maximum(room.size[:2] - 2 * r, 0.0) + np.minimum(r, room.size[:2] / 2)
    if rng.random() < 0.5:  # most furniture is roughly aligned with the walls
        yaw = rng.integers(0, 4) * np.pi / 2 + rng.normal(0.0, np.radians(4.0))
    else:
        yaw = rng.uniform(-np.pi, np.pi)
    return Pose(xy, 0.0, float(yaw))


def _touching_pose(other: Placed, asm: Assembly, rng: np.random.Generator, face: bool) -> Pose:
    """Next to ``other``: flush against one of its sides, or (``face``, for chairs) facing it, pushed in."""
    olo, ohi = other.assembly.bounds()
    lo, hi = asm.bounds()
    k = int(rng.integers(0, 4))  # which side of the other piece: +x, +y, -x, -y
    direction = np.array([[1, 0], [0, 1], [-1, 0], [0, -1]][k], float)
    # rotate the new piece so that, if it faces the other, its front (+y) points back at it
    yaw_rel = (k * np.pi / 2 + np.pi / 2) if face else rng.integers(0, 4) * np.pi / 2
    c, s = np.cos(yaw_rel), np.sin(yaw_rel)
    rot2 = np.array([[c, -s], [s, c]])
    corners = np.array([[x, y] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])]) @ rot2.T
    nlo, nhi = corners.min(0), corners.max(0)  # the new piece's extent in the other piece's frame
    axis = k % 2
    if direction[axis] > 0:
        offset_axis = ohi[axis] - nlo[axis]
    else:
        offset_axis = olo[axis] - nhi[axis]
    gap = rng.uniform(-0.2, 0.02) if face else 0.0
    pos = np.zeros(2)
    pos[axis] = offset_axis + direction[axis] * gap
    span = (olo[1 - axis] - nlo[1 - axis], ohi[1 - axis] - nhi[1 - axis])
    pos[1 - axis] = rng.uniform(min(span), max(span))
    return Pose(other.pose.apply([pos[0], pos[1], 0.0])[:2], 0.0, float(other.pose.yaw + yaw_rel))


def add_furniture(
    world: World, occ: Occupancy, room: Room, count: int, rng: np.random.Generator
) -> list[Placed]:
    """Place up to ``count`` pieces of floor furniture (and wall cupboards); returns those placed."""
    placed: list[Placed] = []
    for _ in range(count):
        if rng.random() < 0.12:
            asm, kind, wall_prob = wall_cupboard(rng), "wall_cupboard", 1.0
        else:
            kind = _pick(FLOOR_FURNITURE, rng)
            gen, _, wall_prob = FLOOR_FURNITURE[kind]
            asm = gen(rng)
        tables = [p for p in placed if p.assembly.category in ("table", "desk")]
        for _attempt in range(25):
            mode = rng.random()
            if kind == "chair" and tables and mode < 0.7:
                pose = _touching_pose(tables[int(rng.integers(len(tables)))], asm, rng, face=True)
            elif placed and kind not in ("wall_cupboard", "bed") and mode < 0.2:
                pose = _touching_pose(placed[int(rng.integers(len(placed)))], asm, rng, face=False)
            elif mode < wall_prob:
                pose = _wall_pose(room, asm, rng)
            else:
                pose = _free_pose(room, asm, rng)
            if pose is None:
                continue
            oid = place_assembly(world, occ, room, asm, pose, rng)
            if oid is not None:
                if kind != "wall_cupboard":
                    placed.append(Placed(asm, pose, oid))
                break
    return placed


def _surface_pose(
    surface: Surface, owner: Pose, lo: np.ndarray, hi: np.ndarray, rng: np.random.Generator
) -> Pose | None:
    """A random pose of an object with extent lo, hi (3,) standing fully on ``surface`` of ``owner``."""
    if hi[2] - lo[2] > surface.clearance_m - 0.01:
        return None
    yaw = rng.integers(0, 4) * np.pi / 2 + (rng.normal(0.0, 0.3) if rng.random() < 0.5 else 0.0)
    c, s = np.cos(yaw), np.sin(yaw)
    corners = np.array([[x, y] for x in (lo[0], hi[0]) for y in (lo[1], hi[1])]) @ np.array([[c, s], [-s, c]])
    clo, chi = corners.min(0), corners.max(0)
    free_lo, free_hi = surface.lo - clo, surface.hi - chi  # where the origin may go
    if (free_hi < free_lo).any():
        return None
    xy = rng.uniform(free_lo, free_hi)
    return Pose(owner.apply([xy[0], xy[1], surface.z])[:2], owner.z + surface.z, float(owner.yaw + yaw))


def add_small_objects(
    world: World, occ: Occupancy, room: Room, placed: list[Placed], count: int, rng: np.random.Generator
) -> None:
    """Boxes, books, monitors, vases, lamps... standing on tables, desks, cabinets and shelf boards."""
    supports = [(s, p.pose) for p in placed for s in p.assembly.surfaces]
    if not supports:
        return
    area = np.array([np.prod(s.hi - s.lo) for s, _ in supports])
    for _ in range(count):
        surface, owner = supports[int(rng.choice(len(supports), p=area / area.sum()))]
        is_box = rng.random() < 0.6
        asm = (
            SMALL_OBJECTS[_pick(SMALL_OBJECTS, rng)][0](rng)
            if is_box
            else SMALL_CLUTTER[_pick(SMALL_CLUTTER, rng)][0](rng)
        )
        lo, hi = asm.bounds()
        for _attempt in range(8):
            pose = _surface_pose(surface, owner, lo, hi, rng)
            if pose is None:
                break
            if is_box:
                if place_assembly(world, occ, room, asm, pose, rng) is not None:
                    break
            elif place_mesh(world, occ, asm, pose, rng):
                break


def place_mesh(world: World, occ: Occupancy, asm: MeshAssembly, pose: Pose, rng: np.random.Generator) -> bool:
    """Add a clutter object at ``pose`` if its bounding box collides with nothing placed; True if added."""
    lo, hi = asm.bounds()
    box = upright_boxes(pose, lo, hi)
    if occ.collides(*box):
        return False
    occ.add(*box)
    oid = world.new_object(asm.category, MESH)
    mats = _materials_for(world, asm.category, [r for _, _, r in asm.pieces], rng)
    frame = (pose.rotation, pose.apply(np.zeros(3)))
    for v, f, role in asm.pieces:
        world.add_mesh(oid, pose.apply(v), f, mats[role], frame)
    return True


def add_clutter(world: World, occ: Occupancy, room: Room, count: int, rng: np.random.Generator) -> None:
    """Non-box objects on the floor, and sometimes a pipe along a wall."""
    height = float(room.size[2])
    if rng.random() < 0.3:
        asm = pipe(rng, height)
        r = float(asm.bounds()[1][0])
        sides = [s for s in room.sides if s.present]
        side = sides[int(rng.integers(len(sides)))]
        for _attempt in range(8):
            xy = side.to_world(rng.uniform(r, side.length - r), r + rng.uniform(0.0, 0.05))
            if place_mesh(world, occ, asm, Pose(xy, 0.0, side.yaw), rng):
                break
    for _ in range(count):
        asm = FLOOR_CLUTTER[_pick(FLOOR_CLUTTER, rng)][0](rng)
        lo, hi = asm.bounds()
        r = float(np.hypot(*np.maximum(np.abs(lo[:2]), np.abs(hi[:2]))))
        if not (room.size[:2] > 2 * r).all():
            continue
        for _attempt in range(10):
            pose = Pose(rng.uniform(r, room.size[:2] - r), 0.0, float(rng.uniform(-np.pi, np.pi)))
            if place_mesh(world, occ, asm, pose, rng):
                break


def add_lights(world: World, room: Room, rng: np.random.Generator) -> None:
    """One to three ceiling lights inside the room; the first is the brightest (it casts shadows)."""
    n = int(rng.integers(1, 4))
    for k in range(n):
        xy = rng.uniform(0.2, 0.8, 2) * room.size[:2]
        power = rng.uniform(2.5, 4.0) if k == 0 else rng.uniform(0.8, 2.0)
        world.lights.append((np.array([xy[0], xy[1], room.size[2] - rng.uniform(0.05, 0.4)]), float(power)))


def camera_spot(
    room: Room, occ: Occupancy, rng: np.random.Generator, height_m: tuple[float, float]
) -> np.ndarray:
    """A camera position (3,) at least 0.7 m from the room's sides; reserves the space around it."""
    margin = np.minimum(0.7, room.size[:2] / 2 - 0.05)
    xy = rng.uniform(margin, room.size[:2] - margin)
    occ.add(xy, 0.0, [CAMERA_CLEARANCE_M, CAMERA_CLEARANCE_M], [-1.0, room.size[2] + 1.0])
    return np.array([xy[0], xy[1], rng.uniform(*height_m)])

"""The room's structure: floor, ceiling, two to four walls, sometimes a doorway with a door frame and a
corridor behind it. Every structural element is a thin slab (``SLAB`` thick) whose visible face lies on
the surface: the floor slab hangs below z = 0, walls stand outside the room, the ceiling sits on top.

The room's interior is x in [0, size_x], y in [0, size_y], z in [0, height]. A wall side is described in
its own 2D frame: ``a`` along the wall, ``b`` along the inward normal (the room is at b > 0).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from cuboidcli.synth import materials
from cuboidcli.synth.placement import Occupancy
from cuboidcli.synth.world import World

SLAB = 0.05
"""Thickness of wall, floor and ceiling slabs, metres."""


@dataclass
class WallSide:
    """One side of the rectangle: world ``origin`` (2,), unit ``tangent`` (2,), inward ``normal`` (2,),
    interior ``length`` and whether a wall stands there; ``doorway`` = (a0, a1, height) or None."""

    origin: np.ndarray
    tangent: np.ndarray
    normal: np.ndarray
    length: float
    present: bool
    doorway: tuple[float, float, float] | None = None

    @property
    def yaw(self) -> float:
        """Yaw of a frame with x along the wall and y pointing into the room."""
        return float(np.arctan2(self.tangent[1], self.tangent[0]))

    def to_world(self, a: float, b: float) -> np.ndarray:
        return self.origin + a * self.tangent + b * self.normal

    def box(self, a0: float, a1: float, b0: float, b1: float, z0: float, z1: float):
        """(center (3,), half (3,), rotation (3, 3)) of the wall-frame box [a0, a1] x [b0, b1] x [z0, z1]."""
        c = self.to_world((a0 + a1) / 2, (b0 + b1) / 2)
        rot = np.array(
            [[self.tangent[0], self.normal[0], 0.0], [self.tangent[1], self.normal[1], 0.0], [0.0, 0.0, 1.0]]
        )
        return np.array([c[0], c[1], (z0 + z1) / 2]), np.array([a1 - a0, b1 - b0, z1 - z0]) / 2, rot


@dataclass
class Room:
    size: np.ndarray
    """Interior (size_x, size_y, height), metres."""
    sides: list[WallSide] = field(default_factory=list)


def _sides(sx: float, sy: float, present: list[bool]) -> list[WallSide]:
    t = [np.array(v, float) for v in ((1, 0), (0, 1), (-1, 0), (0, -1))]
    origins = [np.array(v, float) for v in ((0, 0), (sx, 0), (sx, sy), (0, sy))]
    lengths = (sx, sy, sx, sy)
    # the inward normal is z x tangent, which keeps every wall frame right-handed
    return [
        WallSide(origins[k], t[k], np.array([-t[k][1], t[k][0]]), lengths[k], present[k]) for k in range(4)
    ]


def _slab(
    world: World, category: str, material: int, side: WallSide, a0, a1, b0, b1, z0, z1, name: str = "slab"
) -> None:
    oid = world.new_object(category)
    world.add_box(oid, name, *side.box(a0, a1, b0, b1, z0, z1), material)


def build_room(world: World, occupancy: Occupancy, rng: np.random.Generator) -> Room:
    """Add the room's structure to ``world``, reserve the doorway in ``occupancy``; returns the room."""
    size = np.array([rng.uniform(3.0, 7.0), rng.uniform(3.0, 7.0), rng.uniform(2.4, 3.1)])
    n_walls = int(rng.choice([2, 3, 4], p=[0.15, 0.25, 0.6]))
    present = [True] * 4
    for k in rng.permutation(4)[: 4 - n_walls]:
        present[k] = False
    room = Room(size, _sides(size[0], size[1], present))
    sx, sy, height = size
    # Where a wall is missing the room opens into a large hall: floor and ceiling continue 6-12 m,
    # far enough for the sensor's range limit to show.
    ext = [SLAB if s.present else rng.uniform(6.0, 12.0) for s in room.sides]
    x0, x1, y0, y1 = -ext[3], sx + ext[1], -ext[0], sy + ext[2]
    wall_mat = world.add_material(materials.sample("wall", rng))
    floor_mat = world.add_material(materials.sample("floor", rng))
    ceil_mat = world.add_material(materials.sample("ceiling", rng))
    floor_side = room.sides[0]  # its frame is the world's
    _slab(world, "floor", floor_mat, floor_side, x0, x1, y0, y1, -SLAB, 0.0)
    _slab(world, "ceiling", ceil_mat, floor_side, x0, x1, y0, y1, height, height + SLAB)
    door_side = None
    if rng.random() < 0.55:
        candidates = [k for k, s in enumerate(room.sides) if s.present and s.length > 1.6]
        if candidates:
            door_side = int(rng.choice(candidates))
    for k, side in enumerate(room.sides):
        if not side.present:
            continue
        # walls run over the floor's whole extent along them; neighbouring slabs overlap in the corners
        prev_ext, next_ext = ext[(k - 1) % 4], ext[(k + 1) % 4]
        a_lo, a_hi = -prev_ext, side.length + next_ext
        if k != door_side:
            _slab(world, "wall", wall_mat, side, a_lo, a_hi, -SLAB, 0.0, 0.0, height)
            continue
        _doorway(world, occupancy, rng, side, a_lo, a_hi, height, wall_mat, floor_mat, ceil_mat)
    return room


def _doorway(
    world: World,
    occupancy: Occupancy,
    rng: np.random.Generator,
    side: WallSide,
    a_lo: float,
    a_hi: float,
    height: float,
    wall_mat: int,
    floor_mat: int,
    ceil_mat: int,
) -> None:
    """A wall with an opening, a door frame (often) and a corridor (or a neighbouring room) behind it."""
    width = rng.uniform(0.8, min(1.6, side.length - 0.8))
    door_h = rng.uniform(2.0, min(2.3, height - 0.15))
    a0 = rng.uniform(0.3, side.length - 0.3 - width)
    a1 = a0 + width
    side.doorway = (a0, a1, door_h)
    oid = world.new_object("wall")
    world.add_box(oid, "slab", *side.box(a_lo, a0, -SLAB, 0.0, 0.0, height), wall_mat)
    world.add_box(oid, "slab", *side.box(a1, a_hi, -SLAB, 0.0, 0.0, height), wall_mat)
    world.add_box(oid, "lintel", *side.box(a0, a1, -SLAB, 0.0, door_h, height), wall_mat)
    if rng.random() < 0.6:
        frame_mat = world.add_material(materials.sample(str(rng.choice(["wood", "painted"])), rng))
        ft, fp = rng.uniform(0.04, 0.07), rng.uniform(0.01, 0.03)
        fid = world.new_object("door_frame")
        world.add_box(fid, "jamb", *side.box(a0, a0 + ft, -SLAB, fp, 0.0, door_h - ft), frame_mat)
        world.add_box(fid, "jamb", *side.box(a1 - ft, a1, -SLAB, fp, 0.0, door_h - ft), frame_mat)
        world.add_box(fid, "head", *side.box(a0, a1, -SLAB, fp, door_h - ft, door_h), frame_mat)
        # (the frame protrudes fp into the room; nothing may stand there)
    # keep the doorway passable: no furniture in front of it
    c, half, _ = side.box(a0, a1, 0.0, 0.9, 0.0, door_h)
    occupancy.add(c[:2], side.yaw, half[:2], [0.0, door_h])
    # the space behind: as wide as the opening or wider, 2.5-9 m deep; sometimes no end wall in range
    c0 = a0 - rng.uniform(0.05, 1.2)
    c1 = a1 + rng.uniform(0.05, 1.2)
    depth = rng.uniform(2.5, 9.0)
    far = -SLAB - depth
    end_wall = rng.random() < 0.75
    if not end_wall:
        far = -SLAB - rng.uniform(11.0, 14.0)
    mat = world.add_material(materials.sample("wall", rng)) if rng.random() < 0.5 else wall_mat
    _slab(world, "floor", floor_mat, side, c0 - SLAB, c1 + SLAB, far - SLAB, -SLAB, -SLAB, 0.0)
    _slab(world, "ceiling", ceil_mat, side, c0 - SLAB, c1 + SLAB, far - SLAB, -SLAB, height, height + SLAB)
    _slab(world, "wall", mat, side, c0 - SLAB, c0, far - SLAB, -SLAB, 0.0, height)
    _slab(world, "wall", mat, side, c1, c1 + SLAB, far - SLAB, -SLAB, 0.0, height)
    if end_wall:
        _slab(world, "wall", mat, side, c0 - SLAB, c1 + SLAB, far - SLAB, far, 0.0, height)

"""Whole objects of a room: which cuboids and which remaining points make up one piece of furniture, and an
upright box around it.

The estimator abstracts a room into parts: a table is its top (a thin slab), a chair its seat, a sofa its
seat and back; legs, stands and thin rims are explained by no cuboid. People who want the furniture (a robot
planning around a table, a detector-style evaluation) need one box per object, legs included. This step
groups, after the fit, without changing the cuboids:

1. The candidate points are the fitting points that are not the room's shell: not inliers of a floor, wall
   or ceiling cuboid, not within :data:`SHELL_CLEARANCE` voxels of a wall or a ceiling nor within
   :data:`FLOOR_CLEARANCE_M` of a floor, and that far above the floor under them
   (:func:`~cuboidcli.fitting.floors.floor_heights`).
2. Seeds: the inliers of each object cuboid, split into the pieces that touch closely (points at most
   :data:`SEED_REACH` voxels apart along every axis). One cuboid laid over two tables gives two seeds;
   pieces of fewer than :data:`MIN_SEED_POINTS` points are no seed.
3. Every other candidate point joins the seed nearest to it through touching points (at most
   :data:`REACH` voxels apart along every axis; a breadth-first growth, at most :data:`GROW_LIMIT_M`):
   legs join their table top, a chair's back its seat.
4. Candidate points no seed reaches form objects of their own when they hold at least
   :data:`MIN_OBJECT_POINTS` points (a bag or a ball that no cuboid explains).
5. Each group's box is upright (its vertical axis the room's up), turned to the yaw of its cuboid (of its
   points' principal axis for a group without one), around its points; a box that comes within
   :data:`FLOOR_TOUCH` voxels of the floor stands on it, and so does a low box or a table top or a seat
   floating at table height (:data:`STAND_TOP_M`): its legs were too thin for the scan. A group whose box
   holds two or more pieces of one level slab lying apart (two seats under one back), or a back with such
   pieces beside it, is shared out among them first (:mod:`~cuboidcli.fitting.seats`).
6. Each object gets a score in [0, 1], how sure the grouping is that the box holds one object
   (:func:`object_score`); detection-style evaluations rank the boxes by it.
7. Boxes that are the wall's own (:func:`~cuboidcli.fitting.not_objects.on_wall`; thicker ones flat
   against a wall when they have its colour, :func:`~cuboidcli.fitting.not_objects.wall_coloured`, unless
   they stand on the floor at a door's size, :func:`~cuboidcli.fitting.not_objects.door_panel`),
   boxes high in the room (:func:`~cuboidcli.fitting.not_objects.high_up`: low-scored ones, and ones no
   cuboid seeded above a door's top), flat patches of floor the floor's cuboids missed
   (:func:`~cuboidcli.fitting.not_objects.is_floor_patch`) and boxes from the floor to the ceiling
   (:func:`~cuboidcli.fitting.not_objects.floor_to_ceiling`) are left out. Then a kept box touching a larger
   kept box from below joins it: a chair's base under its seat (:func:`~cuboidcli.fitting.nested.join_under`);
   then what hangs on a wall, resting on nothing and too high to stand on legs the scan missed, is left
   out (:func:`~cuboidcli.fitting.not_objects.hangs_on_wall`).
8. A sink set into an object's top gets a box of its own (:func:`~cuboidcli.fitting.basins.find_basins`).

These boxes recall most of a room's furniture at 3D IoU 0.25 where the parts recall few (docs/scenes.md).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.basins import object_basins
from cuboidcli.fitting.box import ROBUST_PERCENTILES
from cuboidcli.fitting.door_leaves import door_leaves
from cuboidcli.fitting.doors import door_walls
from cuboidcli.fitting.floors import floor_heights
from cuboidcli.fitting.nested import join_nested, join_under, rests_on
from cuboidcli.fitting.not_objects import (
    door_panel,
    floor_to_ceiling,
    hangs_on_wall,
    high_up,
    is_bent_floor,
    is_floor_patch,
    on_wall,
    wall_coloured,
)
from cuboidcli.fitting.seats import is_level_slab, nearest_piece, pieces_inside
from cuboidcli.geometry.graph import components, grow_labels, touching_pairs
from cuboidcli.geometry.gravity import level_frame

#: Points touch when they lie at most this many voxels apart along every axis (2.75 bridges the one-voxel gaps
#: of thin legs and sparse far surfaces). A distance, not cells of a grid: with cells, where the grid started
#: moved the real scans' precision by up to 2.4 points (docs/scenes.md).
REACH = 2.75
#: A cuboid's inliers are split into pieces whose points touch more closely: at most this many voxels apart
#: along every axis (two table tops a hand apart are two pieces).
SEED_REACH = 1.5
#: A touching piece of a cuboid's inliers seeds an object from this many fitting points on.
MIN_SEED_POINTS = 8
#: A group of points (seeded or not) is an object from this many fitting points on.
MIN_OBJECT_POINTS = 20
#: Points join a seed at most this far from it through touching points (m).
GROW_LIMIT_M = 1.5
#: Points this many voxels or closer to a wall or ceiling cuboid belong to the shell (docs/scenes.md).
SHELL_CLEARANCE = 1.9
#: Points this close (m) or closer to a floor cuboid or to the floor under them belong to the shell, and
#: at least :data:`SHELL_CLEARANCE` voxels: a real floor bends and steps by centimetres whatever the voxel
#: (docs/scenes.md).
FLOOR_CLEARANCE_M = 0.11
#: A group whose box lies at least this much (share of its volume) inside a larger group's box joins it when
#: their colours agree (:func:`~cuboidcli.fitting.nested.join_nested`).
MERGE_OVERLAP = 0.9
#: A box whose lowest point is within this many voxels of the floor is extended down to it (within as many
#: more as the floor's clearance exceeds :data:`SHELL_CLEARANCE` voxels).
FLOOR_TOUCH = 3.0
#: Furniture stands on the floor, but a scan often misses what holds it up (thin legs, a chair's underside in
#: the shadow of its seat). A floating box whose top is at most STAND_TOP_M[1] above its floor is extended
#: down to the floor when its bottom is at most :data:`STAND_LOW_M` up, or when one of its seeds is a level
#: slab (a table top, a seat) at least :data:`STAND_FOOT_M` across with its top from STAND_TOP_M[0] up; its
#: score stays that of what was seen. On the 10 real ScanNet scans (seeds 0-2) recall at IoU 0.25 went from
#: 52-57 % to 59 %, on the sequences rendered from them from 44-45 % to 49-54 % (docs/scenes.md).
STAND_TOP_M = (0.4, 1.1)
STAND_LOW_M = 0.45
STAND_FOOT_M = 0.5
#: The score's support term is 1 - exp(-points / SCORE_POINTS), half its weight at about 280 fitting points
#: (AP@25 on real ScanNet scenes 1-3: 18.2 % at 50, 27.5 % at 400; scenes 4-5, chosen on nothing: 17.1, 18.7).
SCORE_POINTS = 400.0
#: The score's fill term counts the occupied cells of this many voxels in the box's projections.
SCORE_CELL = 2.0
#: The score's factor for a box that does not stand on the floor.
SCORE_FLOATING = 0.7


@dataclass
class SceneObject:
    """One object of a room: its upright box (kind ``object``), the cuboids (indices in selection order) that
    seeded it (none for points no cuboid explains, or for a box that the fits voting on the boxes found and
    the returned fit did not: :mod:`~cuboidcli.fitting.consensus`), how many fitting points it holds, its
    score in [0, 1] (:func:`object_score`) and what it is: ``door`` (steps 8-9), ``sink`` (step 7) or
    ``object``."""

    box: Cuboid
    cuboids: tuple[int, ...]
    points: int
    score: float = 0.0
    kind: str = "object"

    def to_dict(self, index: int) -> dict:
        c = self.box
        return {
            "id": index,
            "center": [round(float(v), 6) for v in c.center],
            "half_size": [round(float(v), 6) for v in c.half_size],
            "rotation": [[round(float(v), 6) for v in row] for row in c.rotation],
            "quat_wxyz": [round(float(v), 6) for v in c.quat_wxyz],
            "cuboids": list(self.cuboids),
            "points": self.points,
            "score": round(float(self.score), 4),
            "kind": self.kind,
        }


def _outside_distance(points: np.ndarray, c: Cuboid) -> np.ndarray:
    """(N,) distance of each point from the solid box ``c`` (0 inside)."""
    local = (points - c.center) @ c.rotation
    return np.linalg.norm(np.maximum(np.abs(local) - c.half_size, 0.0), axis=1)


def _yaw(rotation_level: np.ndarray) -> float:
    """The heading (radians about the level frame's z) of a box's most horizontal axis."""
    k = int(np.argmax(np.linalg.norm(rotation_level[:2], axis=0)))
    return math.atan2(rotation_level[1, k], rotation_level[0, k])


def _principal_yaw(xy: np.ndarray) -> float:
    """The heading of the principal axis of points (N, 2) on the floor plane."""
    d = xy - xy.mean(0)
    _, vecs = np.linalg.eigh(d.T @ d)
    return math.atan2(vecs[1, 1], vecs[0, 1])


def _yaw_matrix(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _coverage(uv: np.ndarray, size: np.ndarray, cell_m: float) -> float:
    """Share of the cells (side ``cell_m``) of the rectangle [0, size] (2,) that hold a point of (N, 2)."""
    dims = np.maximum(np.ceil(size / cell_m).astype(np.int64), 1)
    ij = np.clip(np.floor(uv / cell_m).astype(np.int64), 0, dims - 1)
    return len(np.unique(ij[:, 0] * dims[1] + ij[:, 1])) / float(dims[0] * dims[1])


def object_score(local: np.ndarray, lo: np.ndarray, hi: np.ndarray, voxel_m: float, grounded: bool) -> float:
    """How sure the grouping is that a box holds one whole object, in [0, 1]: support x fill x stance.

    ``local`` (N, 3) are the object's fitting points in its box's frame (level, turned to its heading; z
    up), the box spans ``lo`` to ``hi`` (3,) there, ``voxel_m`` is the fitting voxel and ``grounded`` says
    whether the box stands on the floor.

    - support, 1 - exp(-N / :data:`SCORE_POINTS`): a handful of points is as likely a scrap of a surface
      (a rim, a cable, noise) as an object;
    - fill, the mean of two shares of occupied cells (:data:`SCORE_CELL` voxels): of the box's top view,
      and of the better of its two side views. A scanned object covers its top view (a seat, a table
      top, a shelf's boards) and one side from floor to top (a front, a back); a box that spans two
      objects, or an object and a stray piece of another, holds an empty gap in both;
    - stance, 1 on the floor and :data:`SCORE_FLOATING` off it: furniture stands; what floats is more often a
      fragment of a wall's fixtures or something on a table.
    """
    n = len(local)
    if n == 0:
        return 0.0
    support = 1.0 - math.exp(-n / SCORE_POINTS)
    cell = SCORE_CELL * voxel_m
    rel, size = local - lo, hi - lo
    top = _coverage(rel[:, [0, 1]], size[[0, 1]], cell)
    side = max(_coverage(rel[:, [0, 2]], size[[0, 2]], cell), _coverage(rel[:, [1, 2]], size[[1, 2]], cell))
    fill = 0.5 * (top + side)
    return float(support * fill * (1.0 if grounded else SCORE_FLOATING))


def _stands_on_legs(
    member_groups: np.ndarray,
    seeds: list[int],
    ceiling: np.ndarray,
    lo: np.ndarray,
    hi: np.ndarray,
    floor_z: float,
) -> bool:
    """Whether a floating box (``lo``, ``hi`` in its level frame) is furniture whose lower part the scan
    missed (:data:`STAND_TOP_M`): its top at most STAND_TOP_M[1] above ``floor_z`` and its bottom at most
    :data:`STAND_LOW_M`, or one of its seeds a level slab (``ceiling`` finite) at least
    :data:`STAND_FOOT_M` across with its top from STAND_TOP_M[0] up."""
    bottom, top = float(lo[2]) - floor_z, float(hi[2]) - floor_z
    if top > STAND_TOP_M[1]:
        return False
    if bottom <= STAND_LOW_M:
        return True
    slab = any(seeds[g] >= 0 and np.isfinite(ceiling[g]) for g in np.unique(member_groups) if g >= 0)
    wide = min(float(hi[0] - lo[0]), float(hi[1] - lo[1])) >= STAND_FOOT_M
    return slab and wide and top >= STAND_TOP_M[0]


def group_objects(
    points: np.ndarray,
    labels: np.ndarray,
    cuboids: list[Cuboid],
    up: np.ndarray,
    voxel_m: float,
    colors: np.ndarray | None = None,
) -> list[SceneObject]:
    """The objects of a fitted room (module docstring), largest first.

    ``points`` (M, 3) are the fitting points (voxel means, world frame), ``labels`` (M,) their assignment
    (cuboid index, -1 none, -2 hidden by or inside a cuboid), ``cuboids`` the fit with their ``kind``,
    ``up`` (3,) the room's up direction, ``voxel_m`` the voxel the points were made with and ``colors``
    (M, 3) the points' colours, 0-255, or None (then no box is told from a wall by its colour)."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    labels = np.asarray(labels).ravel()
    if len(labels) != len(points):
        raise ValueError(f"{len(labels)} labels for {len(points)} points")
    R = level_frame(np.asarray(up, dtype=np.float64))  # world = R @ level, its z the room's up
    level = points @ R
    shell = [i for i, c in enumerate(cuboids) if c.kind != "object"]
    floors = [cuboids[i] for i in shell if cuboids[i].kind == "floor"]
    z = R[:, 2]
    if not len(points):
        return []
    if floors:  # the top surface of the floor under each point
        under = floor_heights(level, floors, R)
    else:
        under = np.full(len(points), float(np.percentile(level[:, 2], ROBUST_PERCENTILES[0])))
    floor_clear = max(SHELL_CLEARANCE * voxel_m, FLOOR_CLEARANCE_M)
    lift = floor_clear - SHELL_CLEARANCE * voxel_m  # what stands on the floor starts that much higher
    keep = ~np.isin(labels, shell) & (level[:, 2] > under + floor_clear)
    for i in shell:
        clear = floor_clear if cuboids[i].kind == "floor" else SHELL_CLEARANCE * voxel_m
        keep &= _outside_distance(points, cuboids[i]) > clear
    # before the candidates: a door's slab or leaf is the shell's (cuboidcli.fitting.doors, .door_leaves)
    found = door_walls(level, labels, cuboids, R, under, colors)
    found += door_leaves(level, labels, cuboids, R, under, colors, [d[1] for d in found])
    doors = [
        SceneObject(box, (i,), len(local), object_score(local, lo, hi, voxel_m, True), "door")
        for i, box, local, lo, hi in found
    ]
    idx = np.flatnonzero(keep)
    n = len(idx)
    if n == 0:
        return doors
    lab = labels[idx]
    pairs = touching_pairs(points[idx], REACH * voxel_m)

    # seeds: touching pieces of each object cuboid's inliers
    close = touching_pairs(points[idx], SEED_REACH * voxel_m)
    same = (lab[close[:, 0]] == lab[close[:, 1]]) & (lab[close[:, 0]] >= 0)
    piece = components(n, close[same])
    group = np.full(n, -1, dtype=np.int64)
    seeds: list[int] = []  # the cuboid of each group; -1 for a group of unexplained points
    roots, counts = np.unique(piece, return_counts=True)
    for root, count in zip(roots, counts, strict=True):
        if count >= MIN_SEED_POINTS and lab[root] >= 0:
            group[piece == root] = len(seeds)
            seeds.append(int(lab[root]))
    # a level slab (a table top, a shelf board) takes what hangs below it, not what stands on it
    # (:func:`~cuboidcli.fitting.seats.is_level_slab`)
    slabs = {i for i, c in enumerate(cuboids) if c.kind == "object" and is_level_slab(c, z)}
    ceiling = np.array([cuboids[p].top(z) + voxel_m if p in slabs else np.inf for p in seeds])
    group = grow_labels(group, pairs, max(1, int(GROW_LIMIT_M / voxel_m)), level[idx, 2], ceiling)

    # points no seed reached: objects of their own
    free = group < 0
    rest = components(n, pairs[free[pairs[:, 0]] & free[pairs[:, 1]]])
    roots, counts = np.unique(rest[free], return_counts=True)
    for root, count in zip(roots, counts, strict=True):
        if count >= MIN_OBJECT_POINTS:
            group[free & (rest == root)] = len(seeds)
            seeds.append(-1)

    # each group's upright box in its own heading; a group mostly inside another's box joins it
    q = level[idx]
    under_q = under[idx]

    def heading(g: int) -> float:
        part = seeds[g]
        if part >= 0:
            return _yaw(R.T @ cuboids[part].rotation)
        return _principal_yaw(q[group == g][:, :2])

    def extent(members: np.ndarray, theta: float) -> tuple[np.ndarray, np.ndarray]:
        local = q[members] @ _yaw_matrix(theta)
        floor_z = float(np.median(under_q[members]))
        lo, hi = local.min(0) - voxel_m / 2, local.max(0) + voxel_m / 2
        if lo[2] < floor_z + FLOOR_TOUCH * voxel_m + lift:
            lo[2] = floor_z
        lo[2] = max(lo[2], floor_z)
        return lo, hi

    groups = {g: np.flatnonzero(group == g) for g in range(len(seeds))}
    groups = {g: m for g, m in groups.items() if len(m) >= MIN_OBJECT_POINTS}
    headings = {g: heading(g) for g in groups}
    # a group's box in a heading, kept until the group changes: the merging passes ask for the same boxes
    # thousands of times in a cluttered room (plain floats: thousands of pairs of 3-vectors are compared)
    known: dict[tuple[int, int], tuple[list[float], list[float], float]] = {}

    def box_of(g: int, h: int) -> tuple[list[float], list[float], float]:
        if (g, h) not in known:
            lo, hi = extent(groups[g], headings[h])
            known[(g, h)] = (lo.tolist(), hi.tolist(), float(np.prod(hi - lo)))
        return known[(g, h)]

    for a in sorted(groups, key=lambda g: -len(groups[g])):  # seats side by side under one back
        if a in groups and (pieces := pieces_inside(a, groups, seeds, slabs, box_of, MERGE_OVERLAP)):
            near = nearest_piece(
                (q[groups[a]] @ _yaw_matrix(headings[a]))[:, :2], [box_of(b, a) for b in pieces]
            )
            for k, b in enumerate(pieces):
                groups[b] = np.concatenate([groups[b], groups[a][near == k]])
            del groups[a]
            known.clear()
    colors = None if colors is None else np.asarray(colors, dtype=np.float64).reshape(-1, 3)

    def forget(a: int, b: int) -> None:
        for k in [k for k in known if a in k or b in k]:
            del known[k]

    join_nested(groups, box_of, forget, MERGE_OVERLAP, None if colors is None else colors[idx])

    walls = [c for c in cuboids if c.kind == "wall"]
    wall_colour: dict[int, np.ndarray] = {}  # the median colour of each wall's inliers
    if colors is not None:
        for j, i in enumerate(i for i, c in enumerate(cuboids) if c.kind == "wall"):
            on = labels == i
            if on.sum() >= MIN_OBJECT_POINTS:
                wall_colour[j] = np.median(colors[on], axis=0)
    objects = []
    for final in (False, True):  # what is left out first; then pieces under a kept box join it
        if final:
            join_under(groups, box_of, forget)
        for g, members in list(groups.items()):
            lo, hi = extent(members, headings[g])
            rotation = R @ _yaw_matrix(headings[g])
            parts = {int(p) for p in np.unique(lab[members]) if p >= 0 and cuboids[int(p)].kind == "object"}
            parts |= {seeds[h] for h in np.unique(group[members]) if seeds[h] >= 0}
            box = Cuboid(rotation @ ((lo + hi) / 2), (hi - lo) / 2, rotation, kind="object")
            floor_z = float(np.median(under_q[members]))
            score = object_score(q[members] @ _yaw_matrix(headings[g]), lo, hi, voxel_m, lo[2] <= floor_z)
            high = high_up(float(lo[2] - floor_z), score, bool(parts))
            heights = q[members, 2] - under_q[members]
            flat = is_floor_patch(heights, float(hi[2] - floor_z)) or is_bent_floor(q[members], heights)
            door = door_panel(
                float(max(hi[0] - lo[0], hi[1] - lo[1])), float(hi[2] - lo[2]), float(lo[2] - floor_z)
            )
            painted = not door and wall_coloured(box, colors, idx[members], walls, wall_colour)
            legs = bool(lo[2] > floor_z) and _stands_on_legs(group[members], seeds, ceiling, lo, hi, floor_z)
            hangs = final and not legs and hangs_on_wall(box, walls, float(lo[2] - floor_z), score)
            wall_piece = on_wall(box, walls, z) or painted or (hangs and not rests_on(g, groups, box_of))
            if flat or high or wall_piece or floor_to_ceiling(float(hi[2] - lo[2]), floor_z, cuboids, z):
                del groups[g]
            if not final or g not in groups:
                continue
            if legs:
                lo = np.array([lo[0], lo[1], floor_z])
                box = Cuboid(rotation @ ((lo + hi) / 2), (hi - lo) / 2, rotation, kind="object")
            objects.append(SceneObject(box, tuple(sorted(parts)), len(members), score))
            turn = _yaw_matrix(headings[g])
            for b_lo, b_hi, low in object_basins(q, q[:, 2] - under_q, members, turn, lo, hi, voxel_m):
                sink = Cuboid(rotation @ ((b_lo + b_hi) / 2), (b_hi - b_lo) / 2, rotation, kind="object")
                objects.append(
                    SceneObject(sink, (), len(low), object_score(low, b_lo, b_hi, voxel_m, False), "sink")
                )
    objects += doors
    objects.sort(key=lambda o: -o.points)
    return objects

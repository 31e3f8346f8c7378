"""A room as the estimator's input: one set of cuboids for a whole room given as points in its own world
frame (a scan, a mesh sampled to points, a fused RGB-D sequence, an array).

The estimator is the frame's (:func:`cuboidcli.fitting.pipeline.estimate`: sample, solve, score, select,
refine, grow, align) on other fitting points and another scoring backend (:func:`room_input`):

- the fitting points are the means of the input's points in cubic voxels (``voxel_m``, grown until at
  most ``fit_points`` remain) instead of an image grid; localised minimal sets search a ball around their
  first point through voxel cells (:mod:`cuboidcli.sampling.space`);
- the points are scored under the room's visibility (:mod:`cuboidcli.geometry.room`): ``views`` when each
  point keeps a camera that saw it (a bare cloud: a virtual one outside its surface), ``inside``, ``plain``;
- gravity and the room's Manhattan axes come from the points' normals (:mod:`cuboidcli.geometry.cloud`),
  and the room's shell is told from furniture seen from inside the room (the cameras' mean position, or
  the middle of the points' bounding box).
"""

from __future__ import annotations

import time

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.align import Alignment
from cuboidcli.fitting.box import ROBUST_PERCENTILES
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.fit_input import FitInput, RoomFitting
from cuboidcli.fitting.floors import floor_heights
from cuboidcli.fitting.room_backend import RoomBackend
from cuboidcli.fitting.seats import is_level_slab
from cuboidcli.geometry.cloud import estimate_normals, room_up, voxel_groups
from cuboidcli.geometry.free_side import free_side_normals
from cuboidcli.geometry.gravity import level_frame
from cuboidcli.geometry.plan import room_outline, share_beyond
from cuboidcli.geometry.room import RoomPoints
from cuboidcli.sampling import SpaceCells

#: An upright slab whose top stays this far below the room's top (the 99th percentile of the points' heights)
#: is furniture, not a wall (m). On the synthetic room scans it turns the backs of sofas, the sides of beds
#: and shelves into objects: shell precision 57 -> 70 % (sequences), 64 -> 80 % (bare clouds), recall equal.
WALL_TOP_GAP_M = 0.5
#: ... unless it is at least :data:`CUT_WALL_TALL_M` tall and :data:`CUT_WALL_LONG_M` long (m): a stretch of
#: wall whose upper part the scan missed (real scans often stop at 1.5-2 m), with nothing behind it. Backs of
#: sofas and sides of beds are lower, ends of shelves shorter. On the 10 real ScanNet scans, seeds 0-2: 4-9
#: such slabs a seed, each seeding wall-sized boxes; precision 72.7 / 66.7 / 69.4
#: -> 75.3 / 70.5 / 70.9 %, recall at IoU 0.25 59.1 -> 57.7 / 58.4 / 58.4 % (the lost matches were those
#: wall boxes overlapping a door in them).
CUT_WALL_TALL_M = 1.2
CUT_WALL_LONG_M = 1.5
#: An object cuboid of a scan with at least this share of its volume beyond the room's outline seen from
#: above (:func:`~cuboidcli.geometry.plan.share_beyond`) is a wall: nothing of the scan lies in the space it
#: claims beyond the room, so its visible side is the room's boundary (a wall fitted with the thickness of
#: what is behind it, a window's recess). On the 10 real ScanNet scans (the saved fits of seeds 0-2,
#: grouped again): precision 76.6 / 74.0 / 73.9 -> 79.8 / 76.3 / 75.0 %, recall at IoU 0.25 61.7 / 63.8 /
#: 61.7 -> 60.4 / 65.1 / 61.7 % (docs/scenes.md).
BEYOND_SHARE = 0.3
#: The same for a sequence, whose points end where its views ended: the front of a refrigerator in a corner
#: ends what they saw, and its cuboid reaches 35-44 % beyond that outline, walls fitted with depth 31-56 %.
#: On the sequences rendered from the real scans (seeds 0-2, over three phases of the objects' voxel grid):
#: precision +1.0 on average (+0.2 to +2.1 in all 9 runs), recall -0.2 (docs/scenes.md).
BEYOND_SHARE_SEEN = 0.45
#: An object cuboid that is a level slab (:func:`~cuboidcli.fitting.seats.is_level_slab`) of at least
#: :data:`LOW_SLAB_AREA_M2`, with its top at most :data:`LOW_SLAB_TOP_M` (m) above the lowest floor cuboid's
#: plane under its centre, is floor: a stretch of a bent floor, a step. Seats and low tables stand higher.
#: On the saved fits of the 10 real ScanNet scans and their sequences (seeds 0-2), 17 such slabs up to 0.6 m
#: held mostly floor, with tops 0.11-0.25 m above it (two at 0.31 and 0.34 m); 24 held chairs, sofas and
#: tables, with tops from 0.34 m up (docs/scenes.md).
LOW_SLAB_TOP_M = 0.25
LOW_SLAB_AREA_M2 = 0.5
#: An object cuboid that is an upright slab of a size in :data:`OPEN_SLABS`, with at most
#: :data:`OPEN_BEHIND_SHARE` of its own points' number lying behind it (seen from inside the room,
#: :data:`OPEN_BEHIND_M` beyond its back face, along its length, at any height), is a wall: a stretch of
#: wall whose upper part the scan missed or another cuboid took, which the low-wall rule made furniture, or
#: a wall fitted with the depth of a door's or window's recess in it. What stands in the room has the room
#: behind it, and what stands against a wall has the wall behind it above its top; the floor lies behind a
#: bed's side. On the saved fits of the 10 real ScanNet scans and their sequences (seeds 0-4, grouped
#: again) precision 76.7 -> 78.0 % (scans) and 76.0 -> 76.7 % (sequences), recall 64.3 -> 64.2 % and
#: 58.4 -> 58.6 % (docs/scenes.md).
#: (thickness at most, length at least) in m: a thin slab of a wall's height or less, or a slab as long as
#: a room's wall whatever its depth up to 1 m (furniture that long stands before a wall, which is behind it).
OPEN_SLABS = ((0.3, 1.2), (1.0, 4.0))
#: ... upright: the cosine of its thin axis with up below this (within 11.5 degrees of level).
OPEN_SLAB_TILT_COS = 0.2
OPEN_BEHIND_SHARE = 0.05
OPEN_BEHIND_M = (0.1, 1.5)


def fitting_voxels(
    points: np.ndarray, voxel_m: float, max_points: int
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """(voxel size used, voxel means (M, 3), voxel of each point (N,), first point of each voxel (M,)) with
    M <= ``max_points``: the voxel grows by the square root of the excess (surfaces fill voxels in two
    dimensions) until it fits."""
    for _ in range(12):
        means, inverse, first = voxel_groups(points, voxel_m)
        if len(means) <= max_points:
            break
        voxel_m *= max(1.05, float(np.sqrt(len(means) / max_points)))
    return voxel_m, means, inverse, first


def room_input(
    points: np.ndarray,
    config: FitConfig,
    viewpoints: np.ndarray | None = None,
    up_hint: np.ndarray | None = None,
    colors: np.ndarray | None = None,
) -> FitInput:
    """A room given as points (N, 3), metres, in its own world frame, as the estimator's input: voxel means
    (``config.voxel_m``, grown until at most ``config.fit_points`` remain), the room's up direction and
    axes (``config.up``, else estimated from the normals: the Manhattan axis nearest ``up_hint`` (3,),
    default +z), and the scoring backend of its visibility.

    ``viewpoints`` (N, 3): a camera centre that observed each point (a fused sequence), or None (a bare
    cloud, seen from virtual viewpoints just outside its surfaces); ``colors`` (N, 3) 0-255 or None: the
    fitting points keep their voxels' mean colour (the objects step reads it). Deterministic for
    ``config.seed``. The points are numpy arrays; the estimator makes them tensors only for a part that
    computes with torch (:func:`cuboidcli.fitting.pipeline.arrays_for`)."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must be (N, 3), got {points.shape}")
    config = config.for_kind("room")
    visibility = "views" if config.visibility == "auto" else config.visibility
    if not config.occlusion_aware:
        visibility = "plain"
    t0 = time.perf_counter()
    voxel, means, inverse, first = fitting_voxels(points, config.voxel_m, config.fit_points)
    # fit in float32 like a frame; the room kernels read the same rounded coordinates
    means = means.astype(np.float32).astype(np.float64)
    timing = {"prepare": time.perf_counter() - t0}

    t = time.perf_counter()
    normals = estimate_normals(means, radius_m=3.0 * voxel)
    hint = np.array([0.0, 0.0, 1.0]) if up_hint is None else np.asarray(up_hint, dtype=np.float64)
    given = None if config.up is None else np.asarray(config.up, dtype=np.float64)
    up = room_up(means, normals, hint, given, seed=config.seed, cameras=viewpoints is not None)
    viewpoint = _inside_point(means, viewpoints)
    alignment = None
    if config.align != "free":
        axes = up.axes if config.align == "manhattan" else None
        alignment = Alignment(config.align, up.up, axes, viewpoint)
    timing["gravity"] = time.perf_counter() - t

    t = time.perf_counter()
    views = None
    if visibility == "views":
        if viewpoints is not None:
            # each voxel keeps the camera of one of its points (a camera that really saw that patch)
            views = np.asarray(viewpoints, dtype=np.float64)[first]
        else:
            views = free_side_viewpoints(means, normals, viewpoint, config.virtual_view_m, 3.0 * voxel)
    room = RoomPoints.build(means, views, visibility)
    voxel_colors = None
    if colors is not None and len(colors) == len(points):
        voxel_colors = np.zeros((len(means), 3))
        np.add.at(voxel_colors, inverse, np.asarray(colors, dtype=np.float64).reshape(-1, 3))
        voxel_colors = (voxel_colors / np.bincount(inverse, minlength=len(means))[:, None])[room.order]
    timing["prepare"] += time.perf_counter() - t
    return FitInput(
        "room",
        room.points.astype(np.float32),
        "cameras" if viewpoints is not None else "none",
        space=SpaceCells.of(room.points),
        backend=RoomBackend(room),
        alignment=alignment,
        down=-up.up,
        viewpoint=viewpoint,
        room=RoomFitting(voxel, visibility, up, room.order, inverse, voxel_colors),
        warnings=[up.warning] if up.warning else [],
        timing_s=timing,
        started=t0,
    )


def low_walls_are_furniture(cuboids: list[Cuboid], points: np.ndarray, up: np.ndarray) -> None:
    """Cuboids of kind ``wall`` whose top stays :data:`WALL_TOP_GAP_M` below the room's top (the 99th
    percentile of the heights of ``points`` (N, 3) along ``up`` (3,), unit) become ``object``: the back of a
    sofa or the side of a bed has the room on one side like a wall, but a wall reaches the room's top. A
    slab as tall and long as a stretch of wall (:data:`CUT_WALL_TALL_M`, :data:`CUT_WALL_LONG_M`) stays a
    wall: the scan missed its upper part."""
    if len(points) == 0:
        return
    room_top = float(np.percentile(points @ up, ROBUST_PERCENTILES[1]))
    for c in cuboids:
        if c.kind != "wall" or c.top(up) >= room_top - WALL_TOP_GAP_M:
            continue
        thin = int(np.argmin(c.half_size))
        side = [a for a in range(3) if a != thin]
        along = min(side, key=lambda a: abs(float(c.rotation[:, a] @ up)))  # the slab's horizontal side
        height = 2.0 * float(np.abs(c.rotation.T @ up) @ c.half_size)
        length = 2.0 * float(c.half_size[along])
        if height < CUT_WALL_TALL_M or length < CUT_WALL_LONG_M:
            c.kind = "object"


def beyond_the_room_is_wall(
    cuboids: list[Cuboid], points: np.ndarray, up: np.ndarray, share: float = BEYOND_SHARE
) -> None:
    """Object cuboids with at least ``share`` of their volume beyond the outline of ``points`` (N, 3) seen
    from above (``up`` (3,), unit) become ``wall``: what stands in the room lies inside its outline
    (:data:`BEYOND_SHARE` for a scan, :data:`BEYOND_SHARE_SEEN` for a sequence, which sees its room in
    part)."""
    if len(points) < 3:
        return
    level = level_frame(up)
    outline = room_outline(points, level)
    for c in (c for c in cuboids if c.kind == "object"):
        if share_beyond(c.center, c.half_size, c.rotation, outline, level) >= share:
            c.kind = "wall"


def open_behind_is_wall(
    cuboids: list[Cuboid], points: np.ndarray, up: np.ndarray, viewpoint: np.ndarray
) -> None:
    """Object cuboids that are long upright slabs (:data:`OPEN_SLABS`) with (almost) nothing behind them,
    seen from ``viewpoint`` (3,) inside the room, become ``wall``: ``points`` (N, 3) are the room's fitting
    points and ``up`` (3,), unit, its up direction."""
    near, far = OPEN_BEHIND_M
    for c in (c for c in cuboids if c.kind == "object"):
        thin = int(np.argmin(c.half_size))
        if abs(float(c.rotation[:, thin] @ up)) >= OPEN_SLAB_TILT_COS:
            continue
        side = [a for a in range(3) if a != thin]
        along = min(side, key=lambda a: abs(float(c.rotation[:, a] @ up)))  # the slab's horizontal side
        thick, length = 2.0 * float(c.half_size[thin]), 2.0 * float(c.half_size[along])
        if not any(thick <= t and length >= n for t, n in OPEN_SLABS):
            continue
        local = (points - c.center) @ c.rotation
        if float(c.rotation[:, thin] @ (c.center - viewpoint)) < 0:
            local[:, thin] = -local[:, thin]  # its back away from the viewpoint
        beside = np.abs(local[:, along]) <= c.half_size[along]
        depth = local[:, thin] - c.half_size[thin]
        behind = int(np.count_nonzero(beside & (depth > near) & (depth <= far)))
        own = int(np.count_nonzero(np.all(np.abs(local) <= c.half_size, axis=1)))
        if behind <= OPEN_BEHIND_SHARE * own:
            c.kind = "wall"


def low_slabs_are_floor(cuboids: list[Cuboid], up: np.ndarray) -> None:
    """Object cuboids that are level slabs of at least :data:`LOW_SLAB_AREA_M2` with their top at most
    :data:`LOW_SLAB_TOP_M` above the lowest floor cuboid's plane under their centre (``up`` (3,), unit) become
    ``floor``. The lowest, not the nearest: a bare cloud's table top can be taken for a floor, and a table
    beside it is not floor for that."""
    floors = [c for c in cuboids if c.kind == "floor"]
    if not floors:
        return
    R = level_frame(up)
    for c in cuboids:
        if c.kind != "object" or not is_level_slab(c, up):
            continue
        if 4.0 * float(np.prod(c.half_size)) / float(c.half_size.min()) < LOW_SLAB_AREA_M2:
            continue  # the area of its two long sides
        centre = (R.T @ c.center)[None]
        lowest = min(float(floor_heights(centre, [f], R)[0]) for f in floors)
        if c.top(up) - lowest <= LOW_SLAB_TOP_M:
            c.kind = "floor"


def free_side_viewpoints(
    points: np.ndarray, normals: np.ndarray, inside: np.ndarray, distance_m: float, cell_m: float
) -> np.ndarray:
    """(N, 3) a viewpoint per point of a bare cloud, ``distance_m`` out of its surface on the side it was
    seen from (:func:`cuboidcli.geometry.free_side.free_side_normals`: where rays cross empty space, else
    towards ``inside``)."""
    return points + distance_m * free_side_normals(points, normals, inside, cell_m)


def _inside_point(points: np.ndarray, viewpoints: np.ndarray | None) -> np.ndarray:
    """A point inside the room to see its shell from: the cameras' mean position, else the middle of the
    points' bounding box (robust to a few stray points: :data:`~cuboidcli.fitting.box.ROBUST_PERCENTILES`)."""
    if viewpoints is not None and len(viewpoints):
        return np.asarray(viewpoints, dtype=np.float64).mean(0)
    lo, hi = np.percentile(points, ROBUST_PERCENTILES, axis=0)
    return (lo + hi) / 2.0

"""The estimator at room scale: one set of cuboids for a whole room given as points in its own world frame
(a scan, a mesh sampled to points, or a fused RGB-D sequence).

It is the frame's estimator (:func:`cuboidcli.fitting.pipeline.fit_points`: sample, solve, score, select,
refine, grow, align) on other fitting points and another scoring backend:

- the fitting points are the means of the input's points in cubic voxels (``voxel_m``, grown until at
  most ``fit_points`` remain) instead of an image grid; localised minimal sets search a ball around their
  first point through voxel cells (:mod:`cuboidcli.sampling.space`);
- the points are scored under the room's visibility (:mod:`cuboidcli.geometry.room`): ``views`` when each
  point keeps a camera that saw it, ``inside`` for a bare cloud, ``plain`` for comparison;
- gravity and the room's Manhattan axes come from the points' normals (:mod:`cuboidcli.geometry.cloud`),
  and the room's shell is told from furniture seen from inside the room (the cameras' mean position, or
  the middle of the points' bounding box).
"""

from __future__ import annotations

import time
from dataclasses import asdict, dataclass, field, replace

import numpy as np
import torch

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.align import Alignment
from cuboidcli.fitting.assign import assign_points
from cuboidcli.fitting.box import ROBUST_PERCENTILES
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.objects import SceneObject, group_objects
from cuboidcli.fitting.pipeline import FitInfo, ProgressFn, fit_points, warm_up_parts
from cuboidcli.fitting.prepare import PreparedPoints
from cuboidcli.fitting.room_backend import RoomBackend, warm_up_room
from cuboidcli.fitting.shell import cuboid_kind
from cuboidcli.geometry.cloud import RoomUp, estimate_normals, free_side_normals, room_up, voxel_groups
from cuboidcli.geometry.room import VISIBILITY, RoomPoints
from cuboidcli.sampling import Sampler, SpaceCells
from cuboidcli.solvers.base import CuboidSolver

#: An upright slab whose top stays this far below the room's top (the 99th percentile of the points' heights)
#: is furniture, not a wall (m). On the synthetic room scans it turns the backs of sofas, the sides of beds
#: and shelves into objects: shell precision 57 -> 70 % (sequences), 64 -> 80 % (bare clouds), recall equal.
WALL_TOP_GAP_M = 0.5
#: Visibility choices: the three kernels and "auto" (views: a bare cloud is seen from virtual cameras).
VISIBILITY_CHOICES = ("auto", *VISIBILITY)


@dataclass(frozen=True)
class SceneConfig:
    """How a room is turned into fitting points and scored; the estimator's own settings stay in
    :class:`FitConfig`."""

    voxel_m: float = 0.035
    """Side of the voxels whose mean points are the fitting points (m); grown when a room gives more than
    ``fit_points``.

    On synthetic room scans (3 rooms, 8 views each) 3.5 cm voxels and up to 40,000 points recall twice
    the furniture boxes of 5 cm and 20,000 (IoU >= 0.25: 28.6 against 14.3 %; AUC@5 88.1 against 84.4 %)
    in twice the time (9.3 against 4.3 s a room); 3 cm and 50,000 add little (32.1 %, 14.9 s)."""
    fit_points: int = 40000
    """At most this many fitting points (the voxel grows until the room gives no more)."""
    max_cuboids: int = 40
    """Upper bound on the number of cuboids of a room."""
    visibility: str = "auto"
    """How points count against a cuboid: ``views`` (a cuboid must not hide a point from the camera that saw
    it), ``inside`` (observed surface points must not lie inside a solid box), ``plain`` (no penalty);
    ``auto`` = views (a bare cloud is seen from virtual cameras just outside its surfaces)."""
    up: tuple[float, float, float] | None = None
    """The up direction in the input's frame; None = estimated (the Manhattan axis nearest the hint)."""
    virtual_view_m: float = 0.5
    """A bare cloud's points are taken as seen from this far out of their surface, on the side rays cross
    empty space (else towards the inside of the room) (m)."""

    def __post_init__(self) -> None:
        if self.visibility not in VISIBILITY_CHOICES:
            raise ValueError(
                f"visibility must be one of {', '.join(VISIBILITY_CHOICES)}, not {self.visibility!r}"
            )
        if not self.voxel_m > 0:
            raise ValueError(f"voxel_m must be positive, got {self.voxel_m}")
        if self.fit_points < 100:
            raise ValueError(f"fit_points must be at least 100, got {self.fit_points}")
        if self.max_cuboids < 1:
            raise ValueError(f"max_cuboids must be at least 1, got {self.max_cuboids}")

    def to_dict(self) -> dict:
        return asdict(self)


@dataclass
class SceneInfo:
    """What happened while fitting a room, beside the estimator's :class:`FitInfo`."""

    fit: FitInfo
    visibility: str
    voxel_m: float
    up: RoomUp
    viewpoint: np.ndarray
    """(3,) where the room's shell is seen from (the cameras' mean, or the middle of the points)."""
    fit_points: np.ndarray
    """(M, 3) the fitting points (voxel means), in block order."""
    fit_labels: np.ndarray
    """(M,) int32: cuboid k >= 0 the point is an inlier of, -1 none, -2 hidden by or inside a cuboid."""
    point_labels: np.ndarray
    """(N,) int32: the label of each input point (that of its voxel's fitting point)."""
    timing_s: dict = field(default_factory=dict)
    objects: list[SceneObject] = field(default_factory=list)
    """The room's whole objects (furniture with its legs, points no cuboid explains), largest first
    (:func:`cuboidcli.fitting.objects.group_objects`)."""


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


def fit_scene(
    points: np.ndarray,
    config: FitConfig,
    scene: SceneConfig,
    *,
    solver: CuboidSolver,
    sampler: Sampler,
    viewpoints: np.ndarray | None = None,
    up_hint: np.ndarray | None = None,
    progress: ProgressFn | None = None,
) -> tuple[list[Cuboid], SceneInfo]:
    """Fit a room given as points (N, 3), metres, in its own world frame.

    ``viewpoints`` (N, 3): a camera centre that observed each point (a fused sequence), or None (a bare
    cloud). ``up_hint`` (3,): the direction the input calls up (default +z). ``config`` holds the
    estimator's settings (tau, Theta's k, hypotheses, align, seed, ...; its ``max_cuboids`` is replaced by
    ``scene.max_cuboids``); ``solver`` and ``sampler`` are built parts as for a frame. Returns the cuboids
    (selection order, each with ``kind`` and ``inlier_gain``) and a :class:`SceneInfo`.
    Deterministic for ``config.seed``."""
    points = np.asarray(points, dtype=np.float64)
    if points.ndim != 2 or points.shape[1] != 3:
        raise ValueError(f"points must be (N, 3), got {points.shape}")
    if getattr(sampler, "name", "") == "learned":
        raise ValueError("the learned sampler weighs the pixels of a depth map; fit a room with sequential")
    visibility = scene.visibility
    if visibility == "auto":
        visibility = "views"
    if not config.occlusion_aware:
        visibility = "plain"
    config = replace(config, max_cuboids=scene.max_cuboids)
    warm_up_room()
    warm_up_parts(solver, sampler)
    t0 = time.perf_counter()
    voxel, means, inverse, first = fitting_voxels(points, scene.voxel_m, scene.fit_points)
    # fit in float32 like a frame; the room kernels read the same rounded coordinates
    means = means.astype(np.float32).astype(np.float64)
    timing = {"prepare": time.perf_counter() - t0}

    t = time.perf_counter()
    normals = estimate_normals(means, radius_m=3.0 * voxel)
    hint = np.array([0.0, 0.0, 1.0]) if up_hint is None else np.asarray(up_hint, dtype=np.float64)
    given = None if scene.up is None else np.asarray(scene.up, dtype=np.float64)
    up = room_up(means, normals, hint, given, seed=config.seed)
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
            views = free_side_viewpoints(means, normals, viewpoint, scene.virtual_view_m, 3.0 * voxel)
    room = RoomPoints.build(means, views, visibility)
    timing["prepare"] += time.perf_counter() - t

    n = len(room.points)
    prep = PreparedPoints(
        points=torch.from_numpy(room.points.astype(np.float32)),
        grid_index=torch.arange(n),
        grid_shape=(1, n),
        depth_grid=torch.zeros(1, n),
        focal_cells=None,
        grid_step=0,
        cells=None,
        space=SpaceCells.of(room.points),
    )
    backend = RoomBackend(room)
    cuboids, info = fit_points(prep, config, solver, sampler, progress, timing, alignment, backend=backend)
    down = -up.up
    for c in cuboids:
        c.kind = cuboid_kind(room.points, c, down, viewpoint)
    low_walls_are_furniture(cuboids, room.points, up.up)
    timing["total"] = time.perf_counter() - t0

    t = time.perf_counter()
    # the labels of a frame's points (fitting/assign.py), with this room's values
    fit_labels = assign_points(
        prep.points,
        cuboids,
        config.tau_sq_m2,
        config.beta,
        config.tau_c_sq_m2,
        config.occlusion_aware,
        backend,
    )
    labels_in_order = np.empty_like(fit_labels)
    labels_in_order[room.order] = fit_labels
    point_labels = labels_in_order[inverse]
    timing["assign"] = time.perf_counter() - t
    t = time.perf_counter()
    objects = group_objects(room.points, fit_labels, cuboids, up.up, voxel)
    timing["objects"] = time.perf_counter() - t
    info.timing_s = {k: round(v, 6) for k, v in timing.items()}
    info.grid_step = 0
    scene_info = SceneInfo(
        fit=info, visibility=visibility, voxel_m=voxel, up=up, viewpoint=viewpoint,
        fit_points=room.points, fit_labels=fit_labels, point_labels=point_labels, timing_s=info.timing_s,
        objects=objects,
    )  # fmt: skip
    return cuboids, scene_info


def low_walls_are_furniture(cuboids: list[Cuboid], points: np.ndarray, up: np.ndarray) -> None:
    """Cuboids of kind ``wall`` whose top stays :data:`WALL_TOP_GAP_M` below the room's top (the 99th
    percentile of the heights of ``points`` (N, 3) along ``up`` (3,), unit) become ``object``: the back of a
    sofa or the side of a bed has the room on one side like a wall, but a wall reaches the room's top."""
    if len(points) == 0:
        return
    room_top = float(np.percentile(points @ up, ROBUST_PERCENTILES[1]))
    for c in cuboids:
        if c.kind == "wall" and c.top(up) < room_top - WALL_TOP_GAP_M:
            c.kind = "object"


def free_side_viewpoints(
    points: np.ndarray, normals: np.ndarray, inside: np.ndarray, distance_m: float, cell_m: float
) -> np.ndarray:
    """(N, 3) a viewpoint per point of a bare cloud, ``distance_m`` out of its surface on the side it was
    seen from (:func:`cuboidcli.geometry.cloud.free_side_normals`: where rays cross empty space, else
    towards ``inside``)."""
    return points + distance_m * free_side_normals(points, normals, inside, cell_m)


def _inside_point(points: np.ndarray, viewpoints: np.ndarray | None) -> np.ndarray:
    """A point inside the room to see its shell from: the cameras' mean position, else the middle of the
    points' bounding box (robust to a few stray points: :data:`~cuboidcli.fitting.box.ROBUST_PERCENTILES`)."""
    if viewpoints is not None and len(viewpoints):
        return np.asarray(viewpoints, dtype=np.float64).mean(0)
    lo, hi = np.percentile(points, ROBUST_PERCENTILES, axis=0)
    return (lo + hi) / 2.0

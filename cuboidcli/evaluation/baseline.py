"""The room abstraction a user would assemble from Open3D: RANSAC planes for the floor and the walls, then
DBSCAN clusters of what is left, one box per plane and per cluster. A reference point for room metrics
(:mod:`.scene`), not a method of the paper.

Planes (``segment_plane``) become thin slabs whose face lies on the plane and whose body extends
:data:`SLAB_M` away from the room's interior (the side of the cloud's centroid), as the synthetic rooms'
shell slabs do: a horizontal plane near the bottom of the cloud is the floor, one near the top (and at
least :data:`CEILING_MIN_M` above the bottom) the ceiling, a vertical plane a wall; any other plane (a
table top, a tilted surface) is left to the clusters. Each DBSCAN cluster (``cluster_dbscan``) becomes an
upright box: the minimum-area rectangle of its points in the horizontal plane (over the directions of
the 2D convex hull's edges) times its height range.
"""

from __future__ import annotations

import math

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.box import ROBUST_PERCENTILES

PLANE_DISTANCE_M = 0.025
"""RANSAC inlier distance of a plane, metres."""
PLANE_ITERATIONS = 1000
"""RANSAC iterations per plane."""
RANSAC_SAMPLE = 20000
"""RANSAC looks at most at this many random points of the cloud; the plane is then refitted to all."""
MIN_PLANE_FRACTION = 0.03
"""A plane needs at least this fraction of the (down-sampled) points, and :data:`MIN_PLANE_POINTS`."""
MIN_PLANE_POINTS = 100
TILT_DEG = 15.0
"""A plane within this angle of horizontal (vertical) may be a floor or a ceiling (a wall)."""
SHELL_BAND_M = 0.3
"""A floor (ceiling) plane lies within this height of the lowest (highest) 1 % of the points."""
CEILING_MIN_M = 1.9
"""A ceiling plane lies at least this far above the lowest points (else the top of a cloud without a
ceiling, a table top say, would pass for one)."""
SLAB_M = 0.05
"""Thickness of a plane's slab, metres."""
DBSCAN_EPS_M = 0.1
"""DBSCAN neighbourhood radius, metres."""
DBSCAN_MIN_POINTS = 10
"""DBSCAN core-point neighbour count."""
MIN_CLUSTER_POINTS = 30
"""Clusters with fewer (down-sampled) points get no box."""


def _convex_hull(xy: np.ndarray) -> np.ndarray:
    """Vertices (K, 2) of the convex hull of points (N, 2) in cyclic order (OpenCV's, in float64)."""
    import cv2

    if len(xy) < 3:
        return xy
    index = cv2.convexHull(xy.astype(np.float32), returnPoints=False).ravel()
    return xy[index]


def min_area_rectangle(xy: np.ndarray) -> tuple[np.ndarray, np.ndarray, float]:
    """The smallest-area rectangle around points (N, 2): centre (2,), half-sizes (2,) and the angle
    (radians, in [0, pi/2)) of its first axis. One of its sides lies along a hull edge (the rotating
    calipers' argument), so trying every hull edge's direction finds it."""
    xy = np.asarray(xy, dtype=np.float64)
    pts = _convex_hull(xy)
    if len(pts) >= 3:
        edges = np.roll(pts, -1, axis=0) - pts
        angles = np.arctan2(edges[:, 1], edges[:, 0]) % (np.pi / 2)
    else:  # fewer than three points, or all on a line: the principal direction
        pts = xy
        vec = (
            np.linalg.svd(xy - xy.mean(0), full_matrices=False)[2][0] if len(xy) > 1 else np.array([1.0, 0.0])
        )
        angles = np.array([math.atan2(vec[1], vec[0]) % (np.pi / 2)])
    c, s = np.cos(angles), np.sin(angles)
    u = pts @ np.stack([c, s])  # (K, A): coordinates along each candidate first axis
    v = pts @ np.stack([-s, c])
    area = (u.max(0) - u.min(0)) * (v.max(0) - v.min(0))
    k = int(np.argmin(area))
    mid_u, mid_v = (u[:, k].max() + u[:, k].min()) / 2, (v[:, k].max() + v[:, k].min()) / 2
    centre = mid_u * np.array([c[k], s[k]]) + mid_v * np.array([-s[k], c[k]])
    half = np.array([u[:, k].max() - u[:, k].min(), v[:, k].max() - v[:, k].min()]) / 2
    return centre, half, float(angles[k])


def _basis(up: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors completing ``up`` to a right-handed frame (e1, e2, up)."""
    helper = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    e1 = helper - (helper @ up) * up
    e1 /= np.linalg.norm(e1)
    return e1, np.cross(up, e1)


def upright_box(points: np.ndarray, up: np.ndarray) -> Cuboid:
    """The upright box (third axis ``up``) around points (N, 3): the minimum-area rectangle of their
    horizontal coordinates times their height range."""
    e1, e2 = _basis(up)
    centre, half, angle = min_area_rectangle(np.stack([points @ e1, points @ e2], 1))
    h = points @ up
    u = math.cos(angle) * e1 + math.sin(angle) * e2
    rot = np.stack([u, np.cross(up, u), up], axis=1)
    mid = centre[0] * e1 + centre[1] * e2 + (h.max() + h.min()) / 2 * up
    return Cuboid(mid, [half[0], half[1], (h.max() - h.min()) / 2], rot)


def _slab(points: np.ndarray, normal: np.ndarray, kind: str, up: np.ndarray, inside: np.ndarray) -> Cuboid:
    """A slab for the plane of ``points`` (N, 3) with unit ``normal``: its face on the plane (the mean
    offset of the points), SLAB_M thick on the side away from ``inside`` (3,), spanning the points."""
    offset = float(np.mean(points @ normal))
    if (inside @ normal) < offset:
        normal, offset = -normal, -offset  # the normal now points into the room
    if kind == "wall":
        # axes: along the wall, the normal, the plane's steepest direction (up for a vertical wall)
        a = up - (up @ normal) * normal
        a /= np.linalg.norm(a)
        rot = np.stack([np.cross(normal, a), normal, a], axis=1)
        local = points @ rot
        lo, hi = local.min(0), local.max(0)
        lo[1], hi[1] = offset - SLAB_M, offset
    else:
        w = normal if normal @ up > 0 else -normal  # keep the box's third axis pointing up
        e1, e2 = _basis(w)
        centre, half, angle = min_area_rectangle(np.stack([points @ e1, points @ e2], 1))
        u = math.cos(angle) * e1 + math.sin(angle) * e2
        rot = np.stack([u, np.cross(w, u), w], axis=1)
        cu = centre @ [math.cos(angle), math.sin(angle)]  # the rectangle's centre along u and v
        cv = centre @ [-math.sin(angle), math.cos(angle)]
        sign = float(normal @ w)  # +1 for a floor, -1 for a ceiling (its normal points down)
        face, back = offset * sign, (offset - SLAB_M) * sign  # coordinates along w
        lo = np.array([cu - half[0], cv - half[1], min(face, back)])
        hi = np.array([cu + half[0], cv + half[1], max(face, back)])
    return Cuboid(rot @ ((lo + hi) / 2), (hi - lo) / 2, rot, kind=kind)


def _refine_plane(points: np.ndarray, model: np.ndarray, rounds: int = 10) -> tuple[np.ndarray, np.ndarray]:
    """Least-squares refit of a RANSAC plane ``model`` (a, b, c, d) to its inliers among points (N, 3),
    repeated until the inlier set stops changing: (unit normal (3,), inlier mask (N,)).

    Open3D's RANSAC draws its samples from threads sharing one generator, so its plane varies a little
    from run to run even with a seed; the refit converges to the same inlier set, which makes the output
    repeatable (and fits the plane to all its inliers rather than to three of them).
    """
    scale = np.linalg.norm(model[:3])
    normal, offset = model[:3] / scale, -model[3] / scale
    on = np.abs(points @ normal - offset) <= PLANE_DISTANCE_M
    for _ in range(rounds):
        if on.sum() < 3:
            break
        centroid = points[on].mean(axis=0)
        normal = np.linalg.svd(points[on] - centroid, full_matrices=False)[2][2]
        new = np.abs(points @ normal - centroid @ normal) <= PLANE_DISTANCE_M
        if np.array_equal(new, on):
            break
        on = new
    return normal, on


def _shell_kind(
    normal: np.ndarray, heights: np.ndarray, low: float, high: float, up: np.ndarray
) -> str | None:
    """floor / ceiling / wall for a plane with unit ``normal`` whose points have ``heights``; None for
    any other plane."""
    c = abs(float(normal @ up))
    if c >= math.cos(math.radians(TILT_DEG)):
        level = float(np.mean(heights))
        if level <= low + SHELL_BAND_M:
            return "floor"
        if level >= high - SHELL_BAND_M and level >= low + CEILING_MIN_M:
            return "ceiling"
        return None
    if c <= math.sin(math.radians(TILT_DEG)):
        return "wall"
    return None


def planes_and_clusters(
    points: np.ndarray,
    up: np.ndarray | None = None,
    max_planes: int = 4,
    voxel_m: float = 0.03,
    seed: int = 0,
) -> list[Cuboid]:
    """Boxes for a room's point cloud (N, 3), metres, in any frame whose vertical is ``up`` (3,)
    (default +z): slabs for up to ``max_planes`` RANSAC planes (kinds floor / wall / ceiling), then
    upright boxes (kind object) for the DBSCAN clusters of the remaining points.

    The cloud is first down-sampled to ``voxel_m`` voxels (0: not at all). RANSAC runs on at most
    :data:`RANSAC_SAMPLE` random points and each plane is then refitted to all its inliers
    (:func:`_refine_plane`); ``seed`` drives that choice and Open3D's generator, and the same input gives
    the same boxes. Planes come first in the list, in the order found, then clusters in DBSCAN's label
    order.
    """
    import open3d as o3d

    up = np.array([0.0, 0.0, 1.0]) if up is None else np.asarray(up, dtype=np.float64)
    up = up / np.linalg.norm(up)
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    points = points[np.isfinite(points).all(axis=1)]
    if len(points) < 3:
        return []
    if hasattr(o3d.utility, "random"):
        o3d.utility.random.seed(int(seed))
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    if voxel_m > 0:
        cloud = cloud.voxel_down_sample(voxel_m)
    rest = np.asarray(cloud.points)
    heights = rest @ up
    low, high = np.percentile(heights, ROBUST_PERCENTILES)
    inside = rest.mean(axis=0)
    min_plane = max(MIN_PLANE_POINTS, int(MIN_PLANE_FRACTION * len(rest)))
    rng = np.random.default_rng(seed)
    boxes, set_aside = [], []
    for _ in range(max_planes):
        if len(rest) < min_plane:
            break
        # RANSAC on a random subset (the refit below uses every point): its cost grows with the points
        sample = (
            rest if len(rest) <= RANSAC_SAMPLE else rest[rng.choice(len(rest), RANSAC_SAMPLE, replace=False)]
        )
        pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(sample))
        model, _ = pcd.segment_plane(PLANE_DISTANCE_M, 3, PLANE_ITERATIONS)
        normal, on = _refine_plane(rest, np.asarray(model, dtype=np.float64))
        if on.sum() < min_plane:
            break
        kind = _shell_kind(normal, rest[on] @ up, low, high, up)
        if kind is None:
            set_aside.append(rest[on])  # not part of the shell: left to the clusters
        else:
            boxes.append(_slab(rest[on], normal, kind, up, inside))
        rest = rest[~on]
    rest = np.concatenate([rest, *set_aside])
    if len(rest) < MIN_CLUSTER_POINTS:
        return boxes
    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(rest))
    labels = np.asarray(pcd.cluster_dbscan(DBSCAN_EPS_M, DBSCAN_MIN_POINTS))
    for label in range(int(labels.max()) + 1 if len(labels) else 0):
        member = rest[labels == label]
        if len(member) >= MIN_CLUSTER_POINTS:
            boxes.append(upright_box(member, up))
    return boxes

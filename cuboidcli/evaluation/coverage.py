"""Image coverage of a cuboid set (paper Sec. 4 "Coverage"): the fraction of image pixels inside the 2D
convex hull of at least one projected cuboid. No visibility test: a box hidden behind another still counts.

Boxes that reach behind the camera are clipped properly. The research code clamped corners behind the
camera to z = 1e-3 before projecting, which moves them to wrong image positions and inflates the hull.
Here each box is first intersected with the half-space in front of a near plane z = ``near_m``: the
vertices of that convex polytope are the box corners with z >= near_m plus the points where the box's
12 edges cross the plane. Perspective projection maps a convex set in front of the camera to a convex
set, so the hull of the projected clipped vertices is exactly the image of the visible-side part of the
box, i.e. the pixels whose viewing ray (z > near_m) meets the box. As near_m -> 0 this is the set of
pixels whose ray meets the box at all; the default 1e-6 m makes the difference invisible at any image
size, and a box containing the camera covers the whole image.

A pixel (u, v) counts as covered when its centre, the integer coordinates used by
:meth:`cuboidcli.camera.Camera.backproject`, lies inside or on the hull.
"""

from __future__ import annotations

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.geometry.plan import convex_hull_2d

#: Pairs of corner indices of :meth:`Cuboid.corners` that differ in one local axis: the 12 box edges.
BOX_EDGES = tuple((k, k ^ bit) for k in range(8) for bit in (1, 2, 4) if k < k ^ bit)


def clip_corners_near(corners: np.ndarray, near_m: float = 1e-6) -> np.ndarray:
    """Vertices of box ∩ {z >= near_m}: corners (8, 3) in :meth:`Cuboid.corners` order -> (K, 3), K <= 14."""
    z = corners[:, 2] - near_m
    kept = [corners[z >= 0.0]]
    for i, j in BOX_EDGES:
        if (z[i] < 0.0) != (z[j] < 0.0):
            t = z[i] / (z[i] - z[j])
            kept.append((corners[i] + t * (corners[j] - corners[i]))[None])
    return np.concatenate(kept, axis=0)


def polygon_area(poly: np.ndarray) -> float:
    """Area of a simple polygon (P, 2) by the shoelace formula, positive for counter-clockwise order."""
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * float(np.dot(x, np.roll(y, -1)) - np.dot(y, np.roll(x, -1)))


def fill_convex(poly: np.ndarray, width: int, height: int) -> np.ndarray:
    """Pixels whose centre lies in the convex counter-clockwise polygon (P, 2): (height, width) bool.

    Row by row, every edge is a half-plane that bounds u from one side, so each row's covered pixels form
    one interval [u_lo, u_hi]; exact for polygons far larger than the image.
    """
    mask = np.zeros((height, width), dtype=bool)
    if len(poly) < 3 or polygon_area(poly) <= 1e-12:
        return mask
    p, q = poly, np.roll(poly, -1, axis=0)
    ex, ey = q[:, 0] - p[:, 0], q[:, 1] - p[:, 1]
    norm = np.hypot(ex, ey)
    ex, ey = ex / norm, ey / norm
    v = np.arange(height, dtype=np.float64)[:, None]
    # inside = left of every edge: ex (v - p_v) - ey (u - p_u) >= 0  <=>  a u <= b with a = ey
    a = ey[None, :]
    b = ex[None, :] * (v - p[None, :, 1]) + ey[None, :] * p[None, :, 0] + 1e-9
    with np.errstate(divide="ignore", invalid="ignore"):
        bound = b / a
    lo = np.where(a < 0, bound, -np.inf).max(axis=1)
    hi = np.where(a > 0, bound, np.inf).min(axis=1)
    empty = ((a == 0) & (b < 0)).any(axis=1)
    u = np.arange(width, dtype=np.float64)[None, :]
    mask[:] = (u >= lo[:, None]) & (u <= hi[:, None]) & ~empty[:, None]
    return mask


def projected_hull(cuboid: Cuboid, camera: Camera, near_m: float = 1e-6) -> np.ndarray:
    """Image-plane convex hull (P, 2) in pixels of the part of ``cuboid`` in front of z = near_m."""
    verts = clip_corners_near(cuboid.corners(), near_m)
    if len(verts) == 0:
        return np.zeros((0, 2))
    uv, _ = camera.project(verts)
    return convex_hull_2d(uv)


def coverage_mask(camera: Camera, cuboids: list[Cuboid], near_m: float = 1e-6) -> np.ndarray:
    """Pixels covered by at least one cuboid's projected hull: (camera.height, camera.width) bool."""
    mask = np.zeros((camera.height, camera.width), dtype=bool)
    for cuboid in cuboids:
        mask |= fill_convex(projected_hull(cuboid, camera, near_m), camera.width, camera.height)
    return mask

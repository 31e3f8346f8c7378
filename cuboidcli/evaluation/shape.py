"""Shape measurements of a cuboid abstraction: how its boxes sit against gravity and the room's axes, how
much of their visible faces the depth points back, and how far the gravity estimate is from the truth.

Per predicted cuboid (:func:`shape_metrics`):

- ``axis_angle_gravity_deg``: the angle between the up vector and the cuboid axis closest to it, in
  [0, 90] degrees (0 = upright box, whatever its yaw).
- ``axis_angle_manhattan_deg``: the largest, over the cuboid's three axes, of the angle between that axis
  and its nearest axis of the room's Manhattan frame, in [0, 54.74] degrees (0 = the box is aligned with
  the room; a box yawed by 10 degrees gives 10).
- ``slab``: the box is a slab by the estimator's rule (:func:`cuboidcli.fitting.winner.thin_axis`: its
  thinnest half-size under a quarter of its middle one).
- ``room``: the slab is one of the room's shell (wall, floor, ceiling) by a rule that needs no labels
  (:func:`cuboidcli.fitting.winner.is_room_slab`: at most 5 % of the frame's points lie more than 15 cm
  beyond it). The share of these within 3 degrees of the room's axes is the alignment measure of walls,
  floor and ceiling on frames without labels.
- ``support``: the share of the cuboid's visible face pixels whose depth point is one of its inliers
  (:func:`support_counts`).

The up vector and the Manhattan frame are the *reference* (:class:`Reference`): the fit's own gravity where
the fit used one (``FitInfo.gravity``, or the ``gravity`` entry of a saved fit), else the frame's known
gravity (synthetic frames: the room's z-up frame in ``world_from_camera`` of the ground-truth file), else
:func:`estimate_gravity` on the frame's depth exactly as an aligned fit would estimate it (the fitting
grid and the fit's seed); its ``source`` says which ("fit", "synthetic", "estimated"; "none" when no
reliable estimate exists: then the angles are undefined).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.raycast import pixel_rays
from cuboidcli.geometry.gravity import Gravity, estimate_gravity

#: A slab counts as Manhattan-aligned when all its axes are within this angle of the room's axes.
SLAB_ALIGNED_DEG = 3.0
#: A gravity estimate counts as good when within this angle of the true down direction.
GRAVITY_GOOD_DEG = 2.0
#: Reference sources, in order of preference.
SOURCES = ("fit", "synthetic", "estimated", "none")


@dataclass(frozen=True)
class Reference:
    """Up and the Manhattan frame that the cuboids' axes are measured against."""

    source: str
    """"fit", "synthetic", "estimated" or "none" (see the module docstring)."""
    up: np.ndarray | None = None
    """(3,) unit up vector in camera coordinates; None for "none"."""
    frame: np.ndarray | None = None
    """(3, 3) room axes as columns (up first); None when only the up vector is known."""


def unsigned_angle_deg(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Angle in degrees between the lines of unit vectors a (..., 3) and b (..., 3), in [0, 90]
    (the sign of the vectors does not matter). atan2 keeps small angles exact (arccos does not)."""
    cross = np.linalg.norm(np.cross(a, b), axis=-1)
    return np.degrees(np.arctan2(cross, np.abs(np.sum(a * b, axis=-1))))


def signed_angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Angle in degrees between unit vectors a and b (3,), in [0, 180]."""
    return float(np.degrees(np.arctan2(np.linalg.norm(np.cross(a, b)), float(a @ b))))


def axis_angles(rotation: np.ndarray, up: np.ndarray, frame: np.ndarray | None) -> tuple[float, float]:
    """(angle of the axis nearest to up, largest angle of an axis to its nearest room axis) in degrees for
    a cuboid with axes the columns of ``rotation`` (3, 3); the second is NaN without ``frame``."""
    axes = rotation.T  # (3 cuboid axes, 3)
    to_up = unsigned_angle_deg(axes, np.broadcast_to(up, (3, 3)))
    gravity = float(to_up.min())
    if frame is None:
        return gravity, math.nan
    # angle of every cuboid axis (rows) to every room axis (columns)
    pair = unsigned_angle_deg(axes[:, None, :], frame.T[None, :, :])
    return gravity, float(pair.min(axis=1).max())


def is_slab(half_size: np.ndarray) -> bool:
    """The estimator's slab rule (:func:`cuboidcli.fitting.winner.thin_axis`)."""
    from cuboidcli.fitting.box import thin_axis

    return thin_axis(np.asarray(half_size, dtype=np.float64)) >= 0


def room_slabs(depth_m: np.ndarray, camera: Camera, cuboids: list[Cuboid], grid_step: int = 8) -> np.ndarray:
    """(M,) bool: which cuboids are slabs of the room's shell
    (:func:`~cuboidcli.fitting.winner.is_room_slab`), judged against the depth map's points on every
    ``grid_step``-th pixel."""
    from cuboidcli.fitting.shell import is_room_slab

    grid = camera.backproject(np.where(valid_depth(depth_m), depth_m, 0.0), grid_step).reshape(-1, 3)
    points = grid[grid[:, 2] > 0].astype(np.float64)
    return np.array([is_room_slab(points, c.center, c.half_size, c.rotation) for c in cuboids], dtype=bool)


def synthetic_reference(world_from_camera) -> Reference:
    """The reference of a synthetic frame from its camera pose in the z-up room frame (4, 4) or (3, 3):
    the rows of the rotation are the room's x, y and z axes in camera coordinates."""
    rot = np.asarray(world_from_camera, dtype=np.float64)[:3, :3]
    u, _, vt = np.linalg.svd(rot)  # the nearest rotation (the file holds rounded decimals)
    rot = u @ vt
    frame = np.stack([rot[2], rot[0], rot[1]], axis=1)  # columns: up, then the two horizontal axes
    return Reference("synthetic", up=frame[:, 0].copy(), frame=frame)


def fit_reference(gravity: Gravity) -> Reference:
    """The reference of a fit that used ``gravity`` (its frame, when it has one, is made vertical by the fit
    already: :func:`cuboidcli.geometry.gravity.manhattan_axes`)."""
    up = np.asarray(gravity.up, dtype=np.float64)
    return Reference("fit", up=up / np.linalg.norm(up), frame=gravity.frame)


def gravity_from_saved(entry) -> Gravity | None:
    """The ``gravity`` entry of a saved "cuboids/1" fit (:meth:`Gravity.to_dict`) as a Gravity, or None
    when absent or malformed."""
    if not isinstance(entry, dict):
        return None
    try:
        down = np.asarray(entry["down"], dtype=np.float64).reshape(3)
        frame = entry.get("manhattan_frame")
        frame = None if frame is None else np.asarray(frame, dtype=np.float64).reshape(3, 3)
    except (KeyError, TypeError, ValueError):
        return None
    if not np.all(np.isfinite(down)) or np.linalg.norm(down) < 1e-9:
        return None
    if frame is not None:
        u, _, vt = np.linalg.svd(frame)  # the file holds rounded decimals
        frame = u @ vt
    return Gravity(
        down=down / np.linalg.norm(down),
        source=str(entry.get("source", "estimated")),
        confidence=float(entry.get("confidence", 0.0)),
        frame=frame,
    )


def estimate_frame_gravity(depth_m: np.ndarray, camera: Camera, grid_step: int, seed: int) -> Gravity | None:
    """:func:`estimate_gravity` on the fitting grid of a depth map, as the estimator computes it for an
    aligned fit (every ``grid_step``-th pixel, the points in float32, missing depth at the origin)."""
    grid = camera.backproject(np.where(valid_depth(depth_m), depth_m, 0.0), grid_step)
    grid = grid.astype(np.float32).astype(np.float64)
    return estimate_gravity(grid, seed=seed)


@njit(parallel=True, cache=True)
def _zbuffer(fx, fy, cx, cy, height, width, cam_local, rots, halves, depth, owner):
    """Nearest cuboid surface on every pixel's ray (the slab test of
    :func:`cuboidcli.evaluation.raycast.ray_box_interval`, fused): fills depth (H, W) and owner (H, W)."""
    for v in prange(height):
        for u in range(width):
            ray = ((u - cx) / fx, (v - cy) / fy, 1.0)
            best = np.inf
            who = -1
            for k in range(rots.shape[0]):
                z_in = -np.inf
                z_out = np.inf
                for a in range(3):
                    d = rots[k, 0, a] * ray[0] + rots[k, 1, a] * ray[1] + rots[k, 2, a] * ray[2]
                    o = cam_local[k, a]
                    h = halves[k, a]
                    if d == 0.0:
                        if abs(o) > h:
                            z_in = np.inf  # parallel to this slab and outside it: a miss
                        continue
                    t1 = (-h - o) / d
                    t2 = (h - o) / d
                    z_in = max(z_in, min(t1, t2))
                    z_out = min(z_out, max(t1, t2))
                hit = z_in if z_in > 0.0 else z_out
                if z_in <= z_out and hit > 0.0 and hit < best:
                    best = hit
                    who = k
            depth[v, u] = best
            owner[v, u] = who


def visible_faces(camera: Camera, cuboids: list[Cuboid]) -> tuple[np.ndarray, np.ndarray]:
    """Which cuboid's surface each pixel sees first, and at which depth: (owner (H, W) int32, -1 = none;
    depth (H, W) metres, inf = none).

    Every pixel's ray is cast against every cuboid (the slab test of
    :func:`cuboidcli.evaluation.raycast.ray_box_interval`): from outside a box the visible surface is where
    the ray enters it, from inside (a room box around the camera) where it leaves; the nearest surface of
    all cuboids wins (a z-buffer; the earlier cuboid on an exact tie).
    """
    h, w = camera.height, camera.width
    depth = np.full((h, w), np.inf)
    owner = np.full((h, w), -1, dtype=np.int32)
    if not cuboids:
        return owner, depth
    rots = np.stack([c.rotation for c in cuboids])
    halves = np.stack([c.half_size for c in cuboids])
    cam_local = np.stack([-c.rotation.T @ c.center for c in cuboids])  # camera centre in each box frame
    _zbuffer(camera.fx, camera.fy, camera.cx, camera.cy, h, w, cam_local, rots, halves, depth, owner)
    return owner, depth


def support_counts(
    depth_m: np.ndarray,
    camera: Camera,
    cuboids: list[Cuboid],
    labels: np.ndarray,
    tolerance_m: float,
) -> tuple[np.ndarray, np.ndarray]:
    """(visible pixels, supported pixels), each (M,) int, of the M cuboids' visible faces.

    A pixel is *visible* for cuboid k when k's surface is the first cuboid surface on its ray
    (:func:`visible_faces`), its depth is valid and its observed point is not in front of that surface by
    more than ``tolerance_m`` along the ray (a nearer observed point hides the face: an unmodelled object
    before it, which says nothing about the face). It is *supported* when its point is also an inlier of
    k (``labels`` (H, W) == k, the per-pixel assignment of :func:`cuboidcli.fitting.assign.assign_points`).
    Observed points behind the face (the box stands in free space) count as visible and unsupported.
    """
    m = len(cuboids)
    if m == 0:
        return np.zeros(0, dtype=np.int64), np.zeros(0, dtype=np.int64)
    owner, face = visible_faces(camera, cuboids)
    valid = valid_depth(depth_m)
    ray_len = np.linalg.norm(pixel_rays(camera), axis=-1)
    with np.errstate(invalid="ignore"):
        hidden = (face - np.where(valid, depth_m, 0.0)) * ray_len > tolerance_m
    counted = (owner >= 0) & valid & ~hidden
    visible = np.bincount(owner[counted], minlength=m)
    supported = np.bincount(owner[counted & (labels == owner)], minlength=m)
    return visible.astype(np.int64), supported.astype(np.int64)


@dataclass
class ShapeMetrics:
    """The shape measurements of one frame (arrays over its M predicted cuboids, in selection order)."""

    reference: str
    """Source of the up vector / Manhattan frame of the angles: one of :data:`SOURCES`."""
    angle_gravity_deg: np.ndarray
    """(M,) angle between up and the cuboid axis closest to it; NaN without a reference."""
    angle_manhattan_deg: np.ndarray
    """(M,) largest angle of a cuboid axis to its nearest room axis; NaN without a room frame."""
    slab: np.ndarray
    """(M,) bool: the cuboid is a slab (:func:`is_slab`)."""
    room: np.ndarray
    """(M,) bool: the cuboid is a slab of the room's shell (:func:`is_room_slab` on the frame's points)."""
    visible_px: np.ndarray
    """(M,) visible face pixels (:func:`support_counts`)."""
    supported_px: np.ndarray
    """(M,) of those, pixels whose point is an inlier of the cuboid."""
    gravity_error_deg: float = math.nan
    """Angle between the gravity estimate (the fit's, else :func:`estimate_frame_gravity`) and the known
    down direction; NaN without a known gravity or without a reliable estimate."""
    gravity_error_of: str = ""
    """Whose estimate ``gravity_error_deg`` measures: "fit" or "estimated"; "" without a known gravity."""

    @property
    def support(self) -> np.ndarray:
        """(M,) supported / visible pixels, NaN for a cuboid without a visible face pixel."""
        with np.errstate(invalid="ignore", divide="ignore"):
            return np.where(self.visible_px > 0, self.supported_px / np.maximum(self.visible_px, 1), np.nan)

    def _within(self, which: np.ndarray) -> int:
        """Cuboids marked in ``which`` with every axis within :data:`SLAB_ALIGNED_DEG` of the room's axes."""
        return int((which & (self.angle_manhattan_deg <= SLAB_ALIGNED_DEG)).sum())

    def _measured(self, which: np.ndarray) -> int:
        """Cuboids marked in ``which`` whose Manhattan angle is defined (the denominator of their share)."""
        return int((which & np.isfinite(self.angle_manhattan_deg)).sum())

    @property
    def slabs_aligned(self) -> int:
        """Slabs with every axis within :data:`SLAB_ALIGNED_DEG` of the room's axes."""
        return self._within(self.slab)

    @property
    def slabs_measured(self) -> int:
        """Slabs whose Manhattan angle is defined (the denominator of the aligned share)."""
        return self._measured(self.slab)

    @property
    def room_slabs_aligned(self) -> int:
        """Slabs of the room's shell with every axis within :data:`SLAB_ALIGNED_DEG` of the room's axes."""
        return self._within(self.room)

    @property
    def room_slabs_measured(self) -> int:
        """Slabs of the room's shell whose Manhattan angle is defined."""
        return self._measured(self.room)


def shape_metrics(
    depth_m: np.ndarray,
    camera: Camera,
    cuboids: list[Cuboid],
    labels: np.ndarray,
    tolerance_m: float,
    fit_gravity: Gravity | None = None,
    known: Reference | None = None,
    estimate: tuple[int, int] | None = (8, 0),
) -> ShapeMetrics:
    """The shape measurements of one frame (module docstring).

    ``labels`` (H, W): the full-resolution assignment (cuboid index, -1 none, -2 occluded, anything < 0 for
    missing depth). ``tolerance_m``: how far an observed point may lie in front of a face and still count
    for it (the evaluation uses sqrt(tau)). ``fit_gravity``: the gravity the fit used; ``known``: the
    frame's true reference (:func:`synthetic_reference`); ``estimate`` = (grid step, seed) of the fit, for
    :func:`estimate_frame_gravity` when neither gives the reference (None: do not estimate).
    """
    estimated: Gravity | None = None
    done = False

    def estimated_gravity() -> Gravity | None:
        nonlocal estimated, done
        if not done and estimate is not None:
            estimated, done = estimate_frame_gravity(depth_m, camera, *estimate), True
        return estimated

    if fit_gravity is not None:
        ref = fit_reference(fit_gravity)
    elif known is not None:
        ref = known
    elif estimated_gravity() is not None:
        ref = Reference("estimated", up=estimated.up / np.linalg.norm(estimated.up), frame=estimated.frame)
    else:
        ref = Reference("none")
    m = len(cuboids)
    ang_g = np.full(m, math.nan)
    ang_m = np.full(m, math.nan)
    if ref.up is not None:
        for k, c in enumerate(cuboids):
            ang_g[k], ang_m[k] = axis_angles(c.rotation, ref.up, ref.frame)
    visible, supported = support_counts(depth_m, camera, cuboids, labels, tolerance_m)
    out = ShapeMetrics(
        reference=ref.source,
        angle_gravity_deg=ang_g,
        angle_manhattan_deg=ang_m,
        slab=np.array([is_slab(c.half_size) for c in cuboids], dtype=bool),
        room=room_slabs(depth_m, camera, cuboids),
        visible_px=visible,
        supported_px=supported,
    )
    if known is not None:
        if fit_gravity is not None:
            out.gravity_error_of = "fit"
            down = np.asarray(fit_gravity.down, dtype=np.float64)
        else:
            out.gravity_error_of = "estimated"
            g = estimated_gravity()
            down = None if g is None else np.asarray(g.down, dtype=np.float64)
        if down is not None:
            out.gravity_error_deg = signed_angle_deg(down / np.linalg.norm(down), -known.up)
    return out

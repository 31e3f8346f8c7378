"""Ray casting of cuboids through every pixel: depth rendering for tests and a cross-check of coverage."""

from __future__ import annotations

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid


def pixel_rays(camera: Camera) -> np.ndarray:
    """Viewing ray of every pixel centre with unit depth, (H, W, 3): a point at depth z is z * ray."""
    return camera.backproject(np.ones((camera.height, camera.width)))


def ray_box_interval(rays: np.ndarray, cuboid: Cuboid) -> tuple[np.ndarray, np.ndarray]:
    """Depths (z_in, z_out), each (H, W), where rays z * ray (z > 0 unrestricted) enter and leave the box.

    Slab test in the box frame; z_in > z_out means the ray misses the box. z_in may be negative when the
    camera is inside the box or the box reaches behind the camera.
    """
    cam = -cuboid.rotation.T @ cuboid.center  # camera centre in the box frame
    d = rays @ cuboid.rotation  # ray directions in the box frame, (H, W, 3)
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-cuboid.half_size - cam) / d
        t2 = (cuboid.half_size - cam) / d
    lo = np.where(np.isnan(t1), -np.inf, np.minimum(t1, t2))
    hi = np.where(np.isnan(t1), np.inf, np.maximum(t1, t2))
    parallel_out = (d == 0) & (np.abs(cam) > cuboid.half_size)
    lo = np.where(parallel_out, np.inf, lo)
    return lo.max(axis=-1), hi.min(axis=-1)


def render_depth(camera: Camera, cuboids: list[Cuboid]) -> np.ndarray:
    """Depth map (H, W) float32 in metres of the first surface of the cuboids seen from the camera.

    From outside a box the visible surface is where the ray enters it, from inside where it leaves.
    Pixels that see nothing are 0 (missing).
    """
    rays = pixel_rays(camera)
    depth = np.full((camera.height, camera.width), np.inf)
    for cuboid in cuboids:
        z_in, z_out = ray_box_interval(rays, cuboid)
        hit = np.where(z_in > 0, z_in, z_out)
        ok = (z_in <= z_out) & (hit > 0)
        depth = np.where(ok & (hit < depth), hit, depth)
    depth[~np.isfinite(depth)] = 0.0
    return depth.astype(np.float32)


def ray_coverage_mask(camera: Camera, cuboids: list[Cuboid], near_m: float = 1e-6) -> np.ndarray:
    """Pixels whose ray meets a cuboid in front of z = near_m: (H, W) bool, what the hull coverage fills."""
    rays = pixel_rays(camera)
    mask = np.zeros((camera.height, camera.width), dtype=bool)
    for cuboid in cuboids:
        z_in, z_out = ray_box_interval(rays, cuboid)
        mask |= z_out >= np.maximum(z_in, near_m)
    return mask

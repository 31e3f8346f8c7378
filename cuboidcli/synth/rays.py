"""Pixel rays of a camera: one ray per pixel centre, unit z in the camera frame (the convention of
:meth:`cuboidcli.camera.Camera.backproject`), shared by the ray caster and the sensor model."""

from __future__ import annotations

from functools import lru_cache

import numpy as np

from cuboidcli.camera import Camera


@lru_cache(maxsize=8)
def _directions(camera: Camera, step: int) -> np.ndarray:
    u, v = camera.pixel_grid(step)
    d = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones_like(u)], -1)
    d = d.astype(np.float32)
    d.flags.writeable = False  # shared between calls
    return d


def pixel_directions(camera: Camera, step: int = 1) -> np.ndarray:
    """Camera-frame ray directions with z = 1 for every ``step``-th pixel: (H', W', 3) float32, read-only."""
    return _directions(camera, step)

"""Ray casting of oriented boxes from a pinhole camera: the exact z-buffer behind the overlay images.

One pass over the pixels (numba, parallel over image rows) instead of numpy arrays of (H * W, 3) per box:
a 12 MP photo's overlay would otherwise allocate gigabytes and take a minute.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

#: Direction components below this are replaced by +-this, so a ray parallel to a slab gets t = +-huge.
_TINY = 1e-12


@njit(cache=True, parallel=True)
def raycast_boxes(fx, fy, cx, cy, width, height, centers, half_sizes, rotations):
    """Nearest box hit of every pixel's ray.

    The ray of pixel (u, v) is ``t * d`` with ``d = ((u - cx) / fx, (v - cy) / fy, 1)``, so t is the
    z-depth. In the frame of box k (centre c, rotation R, local axes as columns) the ray is
    ``o + t * R^T d`` with ``o = -R^T c``; the slab test gives the entry t_near and exit t_far. A camera
    inside a box sees the box's inside (t_far).

    centers, half_sizes: (K, 3) float64; rotations: (K, 3, 3) float64. Returns depth (H, W) float64 (inf
    where no box is hit), label (H, W) int32 (k, -1 for none) and shade (H, W) float32: |cos| of the angle
    between the ray and the normal of the side hit.
    """
    k_boxes = centers.shape[0]
    origins = np.empty((k_boxes, 3))
    for k in range(k_boxes):
        for j in range(3):
            origins[k, j] = -(
                rotations[k, 0, j] * centers[k, 0]
                + rotations[k, 1, j] * centers[k, 1]
                + rotations[k, 2, j] * centers[k, 2]
            )
    depth = np.full((height, width), np.inf)
    label = np.full((height, width), -1, dtype=np.int32)
    shade = np.zeros((height, width), dtype=np.float32)
    for v in prange(height):
        d_loc = np.empty(3)
        dy = (v - cy) / fy
        for u in range(width):
            dx = (u - cx) / fx
            ray_len = math.sqrt(dx * dx + dy * dy + 1.0)
            best = np.inf
            for k in range(k_boxes):
                t_near = -np.inf
                t_far = np.inf
                axis_near = 0
                axis_far = 0
                for j in range(3):
                    dj = rotations[k, 0, j] * dx + rotations[k, 1, j] * dy + rotations[k, 2, j]
                    if abs(dj) < _TINY:
                        dj = -_TINY if dj < 0 else _TINY
                    d_loc[j] = dj
                    t1 = (-half_sizes[k, j] - origins[k, j]) / dj
                    t2 = (half_sizes[k, j] - origins[k, j]) / dj
                    lo = min(t1, t2)
                    hi = max(t1, t2)
                    if lo > t_near:  # strict: the first axis wins a tie, as argmax does
                        t_near = lo
                        axis_near = j
                    if hi < t_far:
                        t_far = hi
                        axis_far = j
                inside = t_near <= 0.0
                t = t_far if inside else t_near
                axis = axis_far if inside else axis_near
                if t_near <= t_far and t_far > 0.0 and t < best:
                    best = t
                    label[v, u] = k
                    shade[v, u] = abs(d_loc[axis]) / ray_len
            depth[v, u] = best
    return depth, label, shade

"""Independent oracles for the synthetic generator's tests: a numpy ray caster over oriented boxes (the slab
method, no open3d) and box corners. Nothing here calls the code under test."""

from __future__ import annotations

from itertools import product

import numpy as np

SIGNS = np.array(list(product((-1.0, 1.0), repeat=3)))


def corners(center, half_size, rotation) -> np.ndarray:
    """The 8 corners (8, 3) of an oriented box."""
    return (SIGNS * np.asarray(half_size, float)) @ np.asarray(rotation, float).T + np.asarray(center, float)


def cast_boxes(origins: np.ndarray, directions: np.ndarray, boxes) -> tuple[np.ndarray, np.ndarray]:
    """First hit of rays (N, 3) + t (N, 3) on the surfaces of oriented boxes given as (center, half,
    rotation) triples, for t > 0. Returns the ray parameter t (N,) (inf where nothing is hit) and the
    index (N,) of the box hit (-1 where nothing is hit). Rays that start inside a box hit its far side."""
    origins = np.broadcast_to(np.asarray(origins, float), np.shape(directions))
    directions = np.asarray(directions, float)
    best = np.full(len(directions), np.inf)
    index = np.full(len(directions), -1)
    for k, (center, half, rotation) in enumerate(boxes):
        rotation = np.asarray(rotation, float)
        o = (origins - np.asarray(center, float)) @ rotation  # box frame: R^T (o - c)
        d = directions @ rotation
        with np.errstate(divide="ignore", invalid="ignore"):
            t1 = (-np.asarray(half, float) - o) / d
            t2 = (np.asarray(half, float) - o) / d
        # a ray parallel to a slab: inside it for every t, or never
        inside = np.abs(o) <= np.asarray(half, float)
        lo = np.where(d == 0, np.where(inside, -np.inf, np.inf), np.minimum(t1, t2))
        hi = np.where(d == 0, np.where(inside, np.inf, -np.inf), np.maximum(t1, t2))
        t_in, t_out = lo.max(1), hi.min(1)
        t = np.where(t_in > 0, t_in, t_out)
        hit = (t_out >= t_in) & (t > 0)
        closer = hit & (t < best)
        best[closer], index[closer] = t[closer], k
    return best, index


def sphere_directions(n: int) -> np.ndarray:
    """n unit vectors spread evenly over the sphere (Fibonacci lattice): (n, 3)."""
    k = np.arange(n) + 0.5
    z = 1.0 - 2.0 * k / n
    phi = np.pi * (1.0 + 5.0**0.5) * k
    r = np.sqrt(1.0 - z * z)
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], -1)


def pixel_rays(camera) -> np.ndarray:
    """Camera-frame rays with unit z through every pixel centre (pixel (u, v) at integer u, v): (H, W, 3)."""
    v, u = np.mgrid[0 : camera.height, 0 : camera.width].astype(float)
    return np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones_like(u)], -1)

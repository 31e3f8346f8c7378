"""Localised minimal sets in metric 3D space: the first point from the sampling weights, the other C - 1
from a ball around it.

Six points drawn over the whole frame share one structure with probability ~f^6 when that structure holds a
fraction f of the points (1e-4 for f = 0.2, 1e-11 for a chair with 1.6 % of the points), so global minimal
sets find walls and floor but almost never furniture. Drawn from a ball of radius r around a first point,
the six points usually lie on one object, whatever its share of the frame. Radii are drawn per hypothesis
from a multi-scale set (furniture parts to walls). A ball in metres, not a window in the image, keeps a
background point that happens to lie next to a chair in the image out of the chair's minimal set.

The ball members of a seed are the fitting points whose grid cell lies within the image window that the
ball projects to (bounded with the focal length in grid cells and the nearest possible depth) and whose
3D distance to the seed is at most r. They are drawn with replacement in proportion to ``weights``
(points the selected cuboids already explain are drawn less), by one pass over the window with sorted
uniforms: a set's point order does not matter to either solver. The uniforms come from the caller's
generator (numpy's or torch's), so the draws are deterministic for a seed and independent of the thread
count.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from cuboidcli.geometry.arrays import indices_of_generator, numpy64, randint, sorted_uniforms

if TYPE_CHECKING:
    from torch import Tensor

#: Default radii (m) of the balls of localised minimal sets: furniture parts, furniture, large surfaces.
DEFAULT_RADII_M = (0.15, 0.3, 0.6, 1.2)
#: Nearest depth (m) used to bound the image window of a ball.
_NEAR_M = 0.3


@njit(cache=True, parallel=True)
def _ball_sets(points, cell_of_point, point_of_cell, hs, ws, seeds, radii, weights, fcol, frow, u, out):
    """out[h, 0] = seeds[h]; out[h, 1:] drawn from the weighted ball members of the seed (sorted u[h])."""
    n_sets = seeds.shape[0]
    k = u.shape[1]
    for h in prange(n_sets):
        s = seeds[h]
        r = radii[h]
        r2 = r * r
        sx = float(points[s, 0])
        sy = float(points[s, 1])
        sz = float(points[s, 2])
        zn = max(sz - r, _NEAR_M)
        half_c = int(fcol * r / zn) + 1
        half_r = int(frow * r / zn) + 1
        cell = cell_of_point[s]
        row = cell // ws
        col = cell % ws
        r0 = max(row - half_r, 0)
        r1 = min(row + half_r, hs - 1)
        c0 = max(col - half_c, 0)
        c1 = min(col + half_c, ws - 1)
        out[h, 0] = s
        total = 0.0
        for rr in range(r0, r1 + 1):
            for cc in range(c0, c1 + 1):
                j = point_of_cell[rr * ws + cc]
                if j >= 0:
                    dx = points[j, 0] - sx
                    dy = points[j, 1] - sy
                    dz = points[j, 2] - sz
                    if dx * dx + dy * dy + dz * dz <= r2:
                        total += weights[j]
        if total <= 0.0:
            for m in range(k):
                out[h, 1 + m] = s
            continue
        acc = 0.0
        m = 0
        last = s
        for rr in range(r0, r1 + 1):
            if m == k:
                break
            for cc in range(c0, c1 + 1):
                j = point_of_cell[rr * ws + cc]
                if j < 0:
                    continue
                dx = points[j, 0] - sx
                dy = points[j, 1] - sy
                dz = points[j, 2] - sz
                if dx * dx + dy * dy + dz * dz > r2 or weights[j] <= 0.0:
                    continue
                acc += weights[j]
                last = j
                while m < k and u[h, m] * total < acc:
                    out[h, 1 + m] = j
                    m += 1
                if m == k:
                    break
        while m < k:  # rounding at the very end of the cumulative sum
            out[h, 1 + m] = last
            m += 1


def focal_in_cells(points: Tensor, grid_index: Tensor, grid_shape: tuple[int, int]) -> tuple[float, float]:
    """Focal lengths (columns, rows) in grid cells, recovered from the points by least squares.

    A fitting point in grid cell (row, col) satisfies col = fx' x / z + cx' and row = fy' y / z + cy'.
    Used when the caller does not know the camera (the result is exact for a pinhole grid up to rounding).
    """
    p = numpy64(points)
    gi = np.asarray(grid_index).astype(np.int64)
    ws = grid_shape[1]
    if p.shape[0] < 3:
        return 1.0, 1.0
    z = np.maximum(p[:, 2], 1e-6)
    out = []
    for coord, cells in ((p[:, 0] / z, gi % ws), (p[:, 1] / z, gi // ws)):
        a = np.stack([coord, np.ones_like(coord)], 1)
        sol = np.linalg.lstsq(a, cells.astype(np.float64), rcond=None)[0]
        out.append(float(abs(sol[0])) if math.isfinite(float(sol[0])) else 1.0)
    return max(out[0], 1e-3), max(out[1], 1e-3)


def neighbour_weights(state) -> np.ndarray:
    """Weights (N,) float64 of the ball members: 1 - f_OAI for points with state in [0, 1] (unexplained
    points are drawn more), a small weight for occluded points (a new cuboid cannot gain on them)."""
    s = numpy64(state)
    w = np.maximum(1.0 - np.clip(s, 0.0, 1.0), 1e-3)
    return np.where(s < 0, 0.05, w)


def ball_minimal_sets(
    points: Tensor,
    grid_index: Tensor,
    grid_shape: tuple[int, int],
    seeds: Tensor,
    min_set: int,
    generator,
    radii_m: tuple[float, ...] = DEFAULT_RADII_M,
    weights: Tensor | None = None,
    focal_cells: tuple[float, float] | None = None,
) -> Tensor:
    """Minimal sets (S, C) int64: each seed (S,) plus C - 1 points from a ball around it; numpy arrays or
    tensors in, the ``generator``'s kind out (:func:`~cuboidcli.geometry.arrays.indices_of_generator`).

    The radius of each set is drawn uniformly from ``radii_m``; members are drawn with replacement in
    proportion to ``weights`` (N,) (None = equal weights); ``focal_cells`` are the focal lengths in grid
    cells (fx / grid_step, fy / grid_step), estimated from the points when None.
    """
    n_sets = seeds.shape[0]
    out = np.empty((n_sets, min_set), dtype=np.int64)
    if n_sets == 0:
        return indices_of_generator(out, generator)
    hs, ws = grid_shape
    gi = np.asarray(grid_index).astype(np.int64)
    point_of_cell = np.full(hs * ws, -1, dtype=np.int64)
    point_of_cell[gi] = np.arange(gi.size)
    radii = np.asarray(radii_m, dtype=np.float64)
    pick = randint(len(radii_m), n_sets, generator)
    u = sorted_uniforms(n_sets, min_set - 1, generator)
    w = np.ones(points.shape[0]) if weights is None else numpy64(weights)
    fc, fr = focal_cells if focal_cells is not None else focal_in_cells(points, grid_index, grid_shape)
    _ball_sets(
        np.ascontiguousarray(numpy64(points)),
        gi,
        point_of_cell,
        hs,
        ws,
        np.asarray(seeds).astype(np.int64),
        radii[pick],
        np.ascontiguousarray(w),
        float(fc),
        float(fr),
        u,
        out,
    )
    return indices_of_generator(out, generator)


_WARM = False


def warm_up_minimal_sets() -> None:
    """Compile (or load from numba's cache) the kernels that draw localised minimal sets, once per process,
    on tiny inputs: the ball in the image (:func:`ball_minimal_sets`) and the ball among voxel cells
    (:func:`~cuboidcli.sampling.space.space_minimal_sets`). Every sampler's ``warm_up`` calls it."""
    global _WARM
    if _WARM:
        return
    from cuboidcli.sampling.space import SpaceCells, space_minimal_sets

    gen = np.random.default_rng(0)
    p = np.array([[0.0, 0.0, 2.0], [0.1, 0.0, 2.0], [0.2, 0.1, 2.0]])
    ball_minimal_sets(p[:2], np.array([0, 1]), (1, 2), np.array([0]), 6, gen, focal_cells=(60.0, 60.0))
    space_minimal_sets(SpaceCells.of(p), np.array([0]), 6, gen, (0.3,))
    _WARM = True

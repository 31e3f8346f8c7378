"""Localised minimal sets for unorganised points (a room's cloud): the ball around a seed point found through
a voxel grid instead of an image window (:mod:`cuboidcli.sampling.proposals` does it for a depth map).

The points are binned into cubic cells of side :data:`CELL_M`; the members of a ball of radius r around a
seed are the points of the cells the ball's bounding cube reaches whose distance to the seed is at most r.
Members are drawn with replacement in proportion to their weights by one pass with sorted uniforms, as for
frames, and the uniforms come from the caller's generator (numpy's or torch's): deterministic for a seed
and independent of the thread count.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from numba import njit, prange

from cuboidcli.geometry.arrays import indices_of_generator, numpy64, randint, sorted_uniforms

if TYPE_CHECKING:
    from torch import Tensor

#: Side of the cells the ball search visits (m).
CELL_M = 0.25


@dataclass(frozen=True)
class SpaceCells:
    """Points binned by cubic cells: cell k (flat, x-major) holds ``order[start[k]:start[k + 1]]``."""

    points: np.ndarray  # (N, 3) float64
    order: np.ndarray  # (N,) int64
    start: np.ndarray  # (cells + 1,) int64
    origin: np.ndarray  # (3,) the corner of cell (0, 0, 0)
    dims: np.ndarray  # (3,) int64
    cell: float

    @classmethod
    def of(cls, points: np.ndarray, cell: float = CELL_M) -> SpaceCells:
        p = np.ascontiguousarray(points, np.float64)
        origin = p.min(0) if len(p) else np.zeros(3)
        idx = np.floor((p - origin) / cell).astype(np.int64)
        dims = idx.max(0) + 1 if len(p) else np.ones(3, np.int64)
        flat = (idx[:, 0] * dims[1] + idx[:, 1]) * dims[2] + idx[:, 2]
        order = np.argsort(flat, kind="stable").astype(np.int64)
        start = np.searchsorted(flat[order], np.arange(int(np.prod(dims)) + 1)).astype(np.int64)
        return cls(p, order, start, origin, dims.astype(np.int64), float(cell))


@njit(cache=True, parallel=True)
def _space_sets(points, order, start, origin, dims, cell, seeds, radii, weights, u, out):
    k = u.shape[1]
    for h in prange(seeds.shape[0]):
        s = seeds[h]
        r = radii[h]
        r2 = r * r
        sx, sy, sz = points[s, 0], points[s, 1], points[s, 2]
        lo0 = max(int(np.floor((sx - r - origin[0]) / cell)), 0)
        lo1 = max(int(np.floor((sy - r - origin[1]) / cell)), 0)
        lo2 = max(int(np.floor((sz - r - origin[2]) / cell)), 0)
        hi0 = min(int(np.floor((sx + r - origin[0]) / cell)), dims[0] - 1)
        hi1 = min(int(np.floor((sy + r - origin[1]) / cell)), dims[1] - 1)
        hi2 = min(int(np.floor((sz + r - origin[2]) / cell)), dims[2] - 1)
        out[h, 0] = s
        total = 0.0
        for i0 in range(lo0, hi0 + 1):
            for i1 in range(lo1, hi1 + 1):
                base = (i0 * dims[1] + i1) * dims[2]
                for q in range(start[base + lo2], start[base + hi2 + 1]):
                    j = order[q]
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
        for i0 in range(lo0, hi0 + 1):
            for i1 in range(lo1, hi1 + 1):
                base = (i0 * dims[1] + i1) * dims[2]
                for q in range(start[base + lo2], start[base + hi2 + 1]):
                    if m == k:
                        break
                    j = order[q]
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
        while m < k:  # rounding at the very end of the cumulative sum
            out[h, 1 + m] = last
            m += 1


def space_minimal_sets(
    cells: SpaceCells,
    seeds: Tensor,
    min_set: int,
    generator,
    radii_m: tuple[float, ...],
    weights: Tensor | None = None,
) -> Tensor:
    """Minimal sets (S, C) int64: each seed (S,) plus C - 1 points drawn from a ball around it, radius drawn
    uniformly from ``radii_m`` per set, members in proportion to ``weights`` (N,) (None = equal); the
    ``generator``'s kind (:func:`~cuboidcli.geometry.arrays.indices_of_generator`)."""
    n_sets = seeds.shape[0]
    out = np.empty((n_sets, min_set), dtype=np.int64)
    if n_sets == 0:
        return indices_of_generator(out, generator)
    radii = np.asarray(radii_m, dtype=np.float64)
    pick = randint(len(radii_m), n_sets, generator)
    u = sorted_uniforms(n_sets, min_set - 1, generator)
    n = cells.points.shape[0]
    w = np.ones(n) if weights is None else numpy64(weights)
    _space_sets(
        cells.points, cells.order, cells.start, cells.origin, cells.dims, cells.cell,
        np.asarray(seeds).astype(np.int64), radii[pick], np.ascontiguousarray(w), u, out,
    )  # fmt: skip
    return indices_of_generator(out, generator)

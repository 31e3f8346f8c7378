"""Surface normals of an unorganised point cloud by local PCA, in numba loops (no Open3D needed).

The normal of a point is the direction of least spread of its neighbours: the eigenvector of the smallest
eigenvalue of their covariance. The neighbours are the ``max_nn`` nearest points within a radius (the point
itself among them), found through a grid of cubic cells one radius wide (only the occupied cells are
stored), so only the 27 cells around a point are searched. The 3x3 eigenproblem is solved in closed form
(the trigonometric solution of the characteristic cubic, the eigenvector as the largest cross product of
two rows of A - lambda I), the usual fast method for normals.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange


@njit(cache=True)
def _smallest_eigenvector(c, out):
    """Unit eigenvector of the smallest eigenvalue of the symmetric 3x3 ``c`` into ``out``; zeros for a zero
    matrix."""
    scale = 0.0
    for i in range(3):
        for j in range(3):
            scale = max(scale, abs(c[i, j]))
    out[:] = 0.0
    if scale == 0.0:
        return
    a = c / scale
    off = a[0, 1] * a[0, 1] + a[0, 2] * a[0, 2] + a[1, 2] * a[1, 2]
    if off == 0.0:  # diagonal: the axis of the smallest entry
        k = 0
        for i in range(1, 3):
            if a[i, i] < a[k, k]:
                k = i
        out[k] = 1.0
        return
    q = (a[0, 0] + a[1, 1] + a[2, 2]) / 3.0
    b00, b11, b22 = a[0, 0] - q, a[1, 1] - q, a[2, 2] - q
    p = math.sqrt((b00 * b00 + b11 * b11 + b22 * b22 + 2.0 * off) / 6.0)
    c00 = b11 * b22 - a[1, 2] * a[1, 2]
    c01 = a[0, 1] * b22 - a[1, 2] * a[0, 2]
    c02 = a[0, 1] * a[1, 2] - b11 * a[0, 2]
    half_det = (b00 * c00 - a[0, 1] * c01 + a[0, 2] * c02) / (2.0 * p * p * p)
    half_det = min(max(half_det, -1.0), 1.0)
    angle = math.acos(half_det) / 3.0
    smallest = q + 2.0 * p * math.cos(angle + 2.0 * math.pi / 3.0)
    r = a.copy()
    for i in range(3):
        r[i, i] -= smallest
    best, best_norm = -1, 0.0
    cross = np.empty((3, 3))
    for k, (i, j) in enumerate(((0, 1), (0, 2), (1, 2))):
        cross[k, 0] = r[i, 1] * r[j, 2] - r[i, 2] * r[j, 1]
        cross[k, 1] = r[i, 2] * r[j, 0] - r[i, 0] * r[j, 2]
        cross[k, 2] = r[i, 0] * r[j, 1] - r[i, 1] * r[j, 0]
        n = cross[k, 0] ** 2 + cross[k, 1] ** 2 + cross[k, 2] ** 2
        if n > best_norm:
            best, best_norm = k, n
    row, row_norm = 0, 0.0
    for i in range(3):
        n = r[i, 0] ** 2 + r[i, 1] ** 2 + r[i, 2] ** 2
        if n > row_norm:
            row, row_norm = i, n
    if best >= 0 and best_norm > 1e-18 * row_norm * row_norm:
        s = math.sqrt(best_norm)
        for k in range(3):
            out[k] = cross[best, k] / s
        return
    # the two smallest eigenvalues agree (neighbours along a line): any direction across the line
    x, y, z = r[row, 0], r[row, 1], r[row, 2]
    if abs(x) > abs(z):
        u0, u1, u2 = -y, x, 0.0
    else:
        u0, u1, u2 = 0.0, -z, y
    s = math.sqrt(u0 * u0 + u1 * u1 + u2 * u2)
    if s > 0.0:
        out[0], out[1], out[2] = u0 / s, u1 / s, u2 / s


@njit(cache=True, parallel=True)
def _normals(points, order, keys, start, dims, cell_of, r2, max_nn, out):
    for i in prange(points.shape[0]):
        cx, cy, cz = cell_of[i, 0], cell_of[i, 1], cell_of[i, 2]
        n = 0
        for pass_ in range(2):
            if pass_ == 1:
                if n < 3:
                    break
                dist = np.empty(n)
                members = np.empty(n, dtype=np.int64)
                n = 0
            for x in range(max(cx - 1, 0), min(cx + 2, dims[0])):
                for y in range(max(cy - 1, 0), min(cy + 2, dims[1])):
                    base = (x * dims[1] + y) * dims[2]
                    # the occupied cells z-1 .. z+1 of this column are consecutive keys
                    lo = np.searchsorted(keys, base + max(cz - 1, 0))
                    hi = np.searchsorted(keys, base + min(cz + 2, dims[2]))
                    for q in range(start[lo], start[hi]):
                        j = order[q]
                        d = 0.0
                        for k in range(3):
                            d += (points[j, k] - points[i, k]) ** 2
                        if d <= r2:
                            if pass_ == 1:
                                dist[n] = d
                                members[n] = j
                            n += 1
        if n < 3:
            continue
        if n > max_nn:
            members = members[np.argsort(dist, kind="mergesort")[:max_nn]]
            n = max_nn
        mean = np.zeros(3)
        for m in range(n):
            for k in range(3):
                mean[k] += points[members[m], k]
        mean /= n
        cov = np.zeros((3, 3))
        for m in range(n):
            for a in range(3):
                da = points[members[m], a] - mean[a]
                for b in range(a, 3):
                    cov[a, b] += da * (points[members[m], b] - mean[b])
        for a in range(3):
            for b in range(a + 1, 3):
                cov[b, a] = cov[a, b]
        _smallest_eigenvector(cov / n, out[i])


def estimate_normals_pca(points: np.ndarray, radius_m: float, max_nn: int = 24) -> np.ndarray:
    """Unit normals (N, 3) float64 of ``points`` (N, 3): each from its ``max_nn`` nearest neighbours within
    ``radius_m`` (itself included); zeros where fewer than 3 lie that close. Signs are arbitrary."""
    p = np.ascontiguousarray(points, dtype=np.float64)
    out = np.zeros_like(p)
    if len(p) == 0:
        return out
    if not radius_m > 0 or max_nn < 3:
        raise ValueError(f"radius_m must be > 0 and max_nn >= 3, got {radius_m} and {max_nn}")
    cell = np.floor((p - p.min(0)) / radius_m).astype(np.int64)
    dims = cell.max(0) + 1
    flat = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
    order = np.argsort(flat, kind="stable").astype(np.int64)
    # only the occupied cells are listed (a sparse grid: a large extent costs no memory)
    keys, first = np.unique(flat[order], return_index=True)
    start = np.append(first, len(p)).astype(np.int64)
    _normals(p, order, keys, start, dims.astype(np.int64), cell, float(radius_m) ** 2, int(max_nn), out)
    return out

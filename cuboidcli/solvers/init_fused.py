"""CPU fast path of the numerical solver's initial boxes (numba, parallel over minimal sets): the bounding
box in the PCA frame of each set (:func:`~cuboidcli.solvers.numerical.pca_init`) or, for upright boxes, in
the frame turned about z by the principal direction of the horizontal coordinates
(:func:`~cuboidcli.solvers.numerical.upright_init`), as the (centre, axis-angle, half-sizes) rows that
:func:`~cuboidcli.solvers.adam_fused.adam_solve` starts from.

The principal axes come from the 3x3 covariance by Jacobi rotations instead of an SVD of the set: the same
axes up to their signs, which are fixed here so that each axis' largest component is positive (the third
axis completes a right-handed frame). Tests compare the boxes with the torch reference.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

#: Jacobi sweeps at most; a 3x3 symmetric matrix converges to rounding in 4-6.
_SWEEPS = 12


@njit(cache=True)
def _sym_eig3(A, V, w):
    """Eigen-decomposition of the symmetric 3x3 ``A`` (overwritten) by cyclic Jacobi rotations:
    eigenvalues in w (3,), eigenvectors as the columns of V (3, 3), sorted by decreasing eigenvalue."""
    for i in range(3):
        for j in range(3):
            V[i, j] = 1.0 if i == j else 0.0
    for _ in range(_SWEEPS):
        off = A[0, 1] * A[0, 1] + A[0, 2] * A[0, 2] + A[1, 2] * A[1, 2]
        scale = A[0, 0] * A[0, 0] + A[1, 1] * A[1, 1] + A[2, 2] * A[2, 2]
        if off <= 1e-30 * scale or off == 0.0:
            break
        for p in range(2):
            for q in range(p + 1, 3):
                apq = A[p, q]
                if apq == 0.0:
                    continue
                theta = (A[q, q] - A[p, p]) / (2.0 * apq)
                t = (1.0 if theta >= 0 else -1.0) / (abs(theta) + math.sqrt(theta * theta + 1.0))
                c = 1.0 / math.sqrt(t * t + 1.0)
                s = t * c
                for k in range(3):  # A <- J^T A J
                    akp = A[k, p]
                    akq = A[k, q]
                    A[k, p] = c * akp - s * akq
                    A[k, q] = s * akp + c * akq
                for k in range(3):
                    apk = A[p, k]
                    aqk = A[q, k]
                    A[p, k] = c * apk - s * aqk
                    A[q, k] = s * apk + c * aqk
                for k in range(3):
                    vkp = V[k, p]
                    vkq = V[k, q]
                    V[k, p] = c * vkp - s * vkq
                    V[k, q] = s * vkp + c * vkq
    for i in range(3):
        w[i] = A[i, i]
    for i in range(2):  # sort by decreasing eigenvalue
        for j in range(2 - i):
            if w[j] < w[j + 1]:
                w[j], w[j + 1] = w[j + 1], w[j]
                for k in range(3):
                    V[k, j], V[k, j + 1] = V[k, j + 1], V[k, j]


@njit(cache=True, inline="always")
def _matrix_to_axis_angle(R, out):
    """Axis-angle (3,) of the rotation R (3, 3) into out[0:3], through the unit quaternion with w >= 0."""
    t = R[0, 0] + R[1, 1] + R[2, 2]
    if t > R[0, 0] and t > R[1, 1] and t > R[2, 2]:
        w, x, y, z = 1.0 + t, R[2, 1] - R[1, 2], R[0, 2] - R[2, 0], R[1, 0] - R[0, 1]
    elif R[0, 0] >= R[1, 1] and R[0, 0] >= R[2, 2]:
        w, x, y, z = R[2, 1] - R[1, 2], 1.0 + 2.0 * R[0, 0] - t, R[0, 1] + R[1, 0], R[0, 2] + R[2, 0]
    elif R[1, 1] >= R[2, 2]:
        w, x, y, z = R[0, 2] - R[2, 0], R[0, 1] + R[1, 0], 1.0 + 2.0 * R[1, 1] - t, R[1, 2] + R[2, 1]
    else:
        w, x, y, z = R[1, 0] - R[0, 1], R[0, 2] + R[2, 0], R[1, 2] + R[2, 1], 1.0 + 2.0 * R[2, 2] - t
    if w < 0:
        w, x, y, z = -w, -x, -y, -z
    norm = math.sqrt(w * w + x * x + y * y + z * z)
    w, x, y, z = w / norm, x / norm, y / norm, z / norm
    s = math.sqrt(x * x + y * y + z * z)
    if s < 1e-12:
        out[0], out[1], out[2] = 2.0 * x, 2.0 * y, 2.0 * z
        return
    angle = 2.0 * math.atan2(s, w)
    out[0], out[1], out[2] = angle * x / s, angle * y / s, angle * z / s


@njit(cache=True, inline="always")
def _box_in_frame(pts, mean, V, a_min, a_max, out):
    """Centre out[0:3] and half-sizes out[6:9] of the bounding box of ``pts`` (C, 3) in the frame whose
    axes are the columns of V, around the set's ``mean``."""
    lo0 = lo1 = lo2 = 1e300
    hi0 = hi1 = hi2 = -1e300
    for i in range(pts.shape[0]):
        d0 = pts[i, 0] - mean[0]
        d1 = pts[i, 1] - mean[1]
        d2 = pts[i, 2] - mean[2]
        l0 = d0 * V[0, 0] + d1 * V[1, 0] + d2 * V[2, 0]
        l1 = d0 * V[0, 1] + d1 * V[1, 1] + d2 * V[2, 1]
        l2 = d0 * V[0, 2] + d1 * V[1, 2] + d2 * V[2, 2]
        lo0, hi0 = min(lo0, l0), max(hi0, l0)
        lo1, hi1 = min(lo1, l1), max(hi1, l1)
        lo2, hi2 = min(lo2, l2), max(hi2, l2)
    o0, o1, o2 = 0.5 * (lo0 + hi0), 0.5 * (lo1 + hi1), 0.5 * (lo2 + hi2)
    for k in range(3):
        out[k] = mean[k] + V[k, 0] * o0 + V[k, 1] * o1 + V[k, 2] * o2
    out[6] = min(max(0.5 * (hi0 - lo0), a_min), a_max)
    out[7] = min(max(0.5 * (hi1 - lo1), a_min), a_max)
    out[8] = min(max(0.5 * (hi2 - lo2), a_min), a_max)


@njit(cache=True, inline="always")
def _mean(p):
    """Mean (3,) of the points p (C, 3)."""
    mean = np.zeros(3)
    for i in range(p.shape[0]):
        for k in range(3):
            mean[k] += p[i, k]
    return mean / p.shape[0]


@njit(cache=True, parallel=True)
def pca_boxes(pts, a_min, a_max, out):
    """Initial free boxes of minimal sets ``pts`` (H, C, 3) float64 into ``out`` (H, 9) = (centre,
    axis-angle, half-sizes): the bounding box in each set's PCA frame."""
    for h in prange(pts.shape[0]):
        p = pts[h]
        n = p.shape[0]
        mean = _mean(p)
        A = np.zeros((3, 3))
        for i in range(n):
            for j in range(3):
                for k in range(3):
                    A[j, k] += (p[i, j] - mean[j]) * (p[i, k] - mean[k])
        V = np.empty((3, 3))
        w = np.empty(3)
        _sym_eig3(A, V, w)
        for j in range(2):  # a deterministic sign: each axis' largest component positive
            m = 0
            for k in range(1, 3):
                if abs(V[k, j]) > abs(V[m, j]):
                    m = k
            if V[m, j] < 0:
                for k in range(3):
                    V[k, j] = -V[k, j]
        V[0, 2] = V[1, 0] * V[2, 1] - V[2, 0] * V[1, 1]  # right-handed: third = first x second
        V[1, 2] = V[2, 0] * V[0, 1] - V[0, 0] * V[2, 1]
        V[2, 2] = V[0, 0] * V[1, 1] - V[1, 0] * V[0, 1]
        _box_in_frame(p, mean, V, a_min, a_max, out[h])
        _matrix_to_axis_angle(V, out[h, 3:6])


@njit(cache=True, parallel=True)
def upright_boxes(pts, a_min, a_max, fixed, out):
    """Initial upright boxes of minimal sets ``pts`` (H, C, 3) given in a frame whose z axis is up, into
    ``out`` (H, 9): the bounding box in the frame turned about z by the principal direction of the
    horizontal coordinates (not turned when ``fixed``); the axis-angle is (0, 0, yaw)."""
    for h in prange(pts.shape[0]):
        p = pts[h]
        n = p.shape[0]
        mean = _mean(p)
        yaw = 0.0
        if not fixed:
            sxy = sxx = syy = 0.0
            for i in range(n):
                x = p[i, 0] - mean[0]
                y = p[i, 1] - mean[1]
                sxy += x * y
                sxx += x * x
                syy += y * y
            yaw = 0.5 * math.atan2(2.0 * sxy, sxx - syy)
        c, s = math.cos(yaw), math.sin(yaw)
        V = np.zeros((3, 3))
        V[0, 0], V[0, 1], V[1, 0], V[1, 1], V[2, 2] = c, -s, s, c, 1.0
        _box_in_frame(p, mean, V, a_min, a_max, out[h])
        out[h, 3], out[h, 4], out[h, 5] = 0.0, 0.0, yaw

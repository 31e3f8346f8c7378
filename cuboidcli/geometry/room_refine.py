"""The numba Adam refinement of one room cuboid on the points it explains (the room backend's
:meth:`~cuboidcli.fitting.room_backend.RoomBackend.refine`): the mean squared distance of the points to
the box's nearest face, over centre, rotation (axis-angle, Rodrigues) and half-sizes, the half-sizes kept
within bounds; the best iterate. A room's points have no single camera, so the frame's occlusion-aware
distance is replaced by the plain distance to the nearest face."""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cuboidcli.geometry.inlier import to_local


@njit(cache=True)
def _rodrigues(r0, r1, r2):
    """Rotation matrix of the axis-angle vector r."""
    t = math.sqrt(r0 * r0 + r1 * r1 + r2 * r2)
    R = np.eye(3)
    if t < 1e-12:
        return R
    k0, k1, k2 = r0 / t, r1 / t, r2 / t
    c, s, v = math.cos(t), math.sin(t), 1.0 - math.cos(t)
    R[0, 0] = c + k0 * k0 * v
    R[0, 1] = k0 * k1 * v - k2 * s
    R[0, 2] = k0 * k2 * v + k1 * s
    R[1, 0] = k1 * k0 * v + k2 * s
    R[1, 1] = c + k1 * k1 * v
    R[1, 2] = k1 * k2 * v - k0 * s
    R[2, 0] = k2 * k0 * v - k1 * s
    R[2, 1] = k2 * k1 * v + k0 * s
    R[2, 2] = c + k2 * k2 * v
    return R


@njit(cache=True)
def _surface_loss(points, x, grad):
    """Mean squared distance of points to the surface of the box x = (centre, axis-angle, half-sizes), and
    its gradient in the centre and half-sizes (written into ``grad``; the rotation part is left 0)."""
    R = _rodrigues(x[3], x[4], x[5])
    n = points.shape[0]
    loss = 0.0
    for k in range(9):
        grad[k] = 0.0
    gl = np.zeros(3)
    for i in range(n):
        l0, l1, l2 = to_local(points[i, 0] - x[0], points[i, 1] - x[1], points[i, 2] - x[2], R)
        loc = (l0, l1, l2)
        gl[0] = gl[1] = gl[2] = 0.0
        inside = True
        best, kb = 1e300, 0
        for k in range(3):
            q = abs(loc[k]) - x[6 + k]
            sg = 1.0 if loc[k] >= 0 else -1.0
            if q > 0:
                inside = False
                loss += q * q
                gl[k] = 2.0 * q * sg
                grad[6 + k] -= 2.0 * q
            elif -q < best:
                best, kb = -q, k
        if inside:
            loss += best * best
            sg = 1.0 if loc[kb] >= 0 else -1.0
            gl[kb] = -2.0 * best * sg
            grad[6 + kb] += 2.0 * best
        for j in range(3):  # d l / d c = -R^T, so d loss / d c = -R d loss / d l
            grad[j] -= R[j, 0] * gl[0] + R[j, 1] * gl[1] + R[j, 2] * gl[2]
    for k in range(9):
        grad[k] /= n
    return loss / n


@njit(cache=True)
def refine_surface_adam(points, init, a_min, a_max, lr, iters):
    """Adam on the mean squared distance of ``points`` (M, 3) to the box surface, from ``init`` (9,) =
    (centre, axis-angle, half-sizes); the rotation's gradient by central differences. Returns the best
    iterate (9,)."""
    x = init.copy()
    m = np.zeros(9)
    v = np.zeros(9)
    g = np.zeros(9)
    tmp = np.zeros(9)
    best = x.copy()
    best_loss = 1e300
    b1, b2, eps, h = 0.9, 0.999, 1e-8, 1e-6
    for it in range(iters + 1):
        loss = _surface_loss(points, x, g)
        if loss < best_loss:
            best_loss = loss
            best[:] = x
        if it == iters:
            break
        for j in range(3, 6):
            xp = x.copy()
            xp[j] += h
            lp = _surface_loss(points, xp, tmp)
            xp[j] -= 2.0 * h
            lm = _surface_loss(points, xp, tmp)
            g[j] = (lp - lm) / (2.0 * h)
        for j in range(9):
            m[j] = b1 * m[j] + (1.0 - b1) * g[j]
            v[j] = b2 * v[j] + (1.0 - b2) * g[j] * g[j]
            mh = m[j] / (1.0 - b1 ** (it + 1))
            vh = v[j] / (1.0 - b2 ** (it + 1))
            x[j] -= lr * mh / (math.sqrt(vh) + eps)
        for j in range(6, 9):
            x[j] = min(max(x[j], a_min), a_max)
    return best

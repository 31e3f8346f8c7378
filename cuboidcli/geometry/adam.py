"""Fused Adam on one box's parameters p = (centre, axis-angle, half-sizes) (numba, analytic gradients):
Rodrigues' formula and its derivatives, the Adam step with the half-sizes kept in bounds, and the
refinement of a selected cuboid on the mean squared occlusion-aware distance of its inliers
(:func:`refine_adam`; the estimator's winner refinement, :mod:`cuboidcli.fitting.refine`).

The numerical solver's loop (:mod:`cuboidcli.solvers.adam_fused`) runs the same Rodrigues and Adam steps
on its own objective. The rotation gradient uses the closed form of the derivative of Rodrigues' formula
(Gallego and Yezzi, 2015): dR/dr_k = (r_k [r]x + [r x (I - R) e_k]x) R / |r|^2, and [e_k]x at r = 0.
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

from cuboidcli.geometry.inlier import camera_local, occluding_sides


@njit(cache=True, inline="always")
def rodrigues(r0, r1, r2, R):
    th2 = r0 * r0 + r1 * r1 + r2 * r2
    if th2 < 1e-12:
        a = 1.0 - th2 / 6.0
        b = 0.5 - th2 / 24.0
    else:
        th = math.sqrt(th2)
        a = math.sin(th) / th
        b = (1.0 - math.cos(th)) / th2
    # R = I + a K + b K^2 with K = [r]x
    R[0, 0] = 1.0 - b * (r1 * r1 + r2 * r2)
    R[0, 1] = -a * r2 + b * r0 * r1
    R[0, 2] = a * r1 + b * r0 * r2
    R[1, 0] = a * r2 + b * r0 * r1
    R[1, 1] = 1.0 - b * (r0 * r0 + r2 * r2)
    R[1, 2] = -a * r0 + b * r1 * r2
    R[2, 0] = -a * r1 + b * r0 * r2
    R[2, 1] = a * r0 + b * r1 * r2
    R[2, 2] = 1.0 - b * (r0 * r0 + r1 * r1)
    return th2


@njit(cache=True)
def rodrigues_derivatives(r, R, th2, dR):
    """dR[k] = dR/dr_k, (3, 3, 3)."""
    for k in range(3):
        if th2 < 1e-12:
            w0, w1, w2 = (1.0 if k == 0 else 0.0), (1.0 if k == 1 else 0.0), (1.0 if k == 2 else 0.0)
            dR[k, 0, 0] = 0.0
            dR[k, 0, 1] = -w2
            dR[k, 0, 2] = w1
            dR[k, 1, 0] = w2
            dR[k, 1, 1] = 0.0
            dR[k, 1, 2] = -w0
            dR[k, 2, 0] = -w1
            dR[k, 2, 1] = w0
            dR[k, 2, 2] = 0.0
            continue
        # u = (I - R) e_k, then w = r x u; M = (r_k [r]x + [w]x) / |r|^2; dR/dr_k = M R
        u0 = (1.0 if k == 0 else 0.0) - R[0, k]
        u1 = (1.0 if k == 1 else 0.0) - R[1, k]
        u2 = (1.0 if k == 2 else 0.0) - R[2, k]
        w0 = r[1] * u2 - r[2] * u1
        w1 = r[2] * u0 - r[0] * u2
        w2 = r[0] * u1 - r[1] * u0
        s0 = (r[k] * r[0] + w0) / th2
        s1 = (r[k] * r[1] + w1) / th2
        s2 = (r[k] * r[2] + w2) / th2
        # M = [s]x
        for j in range(3):
            dR[k, 0, j] = -s2 * R[1, j] + s1 * R[2, j]
            dR[k, 1, j] = s2 * R[0, j] - s0 * R[2, j]
            dR[k, 2, j] = -s1 * R[0, j] + s0 * R[1, j]


@njit(cache=True, inline="always")
def adam_update(p, m, v, grad, lr, c1, c2, a_min, a_max):
    """One Adam step (torch's defaults: betas 0.9, 0.999, eps 1e-8; c1, c2 the bias corrections), then the
    half-sizes p[6:9] are projected onto [a_min, a_max]."""
    for j in range(9):
        m[j] = 0.9 * m[j] + 0.1 * grad[j]
        v[j] = 0.999 * v[j] + 0.001 * grad[j] * grad[j]
        p[j] -= lr * (m[j] / c1) / (math.sqrt(v[j] / c2) + 1e-8)
    for j in range(6, 9):
        p[j] = min(max(p[j], a_min), a_max)


@njit(cache=True, inline="always")
def _excess_sq(q):
    """Per axis the squared positive excess q^2 where q = |l| - a > 0, else 0: (e0, e1, e2)."""
    e0 = q[0] * q[0] if q[0] > 0 else 0.0
    e1 = q[1] * q[1] if q[1] > 0 else 0.0
    e2 = q[2] * q[2] if q[2] > 0 else 0.0
    return e0, e1, e2


@njit(cache=True)
def _oa_objective_and_grad(pts, p, R, dR, grad):
    """Mean squared occlusion-aware distance d_oa(h, y)^2 of points to one cuboid and its gradient w.r.t.
    p = (t, r, a). The occlusion indicators are piecewise constant and are held fixed."""
    n = pts.shape[0]
    for j in range(9):
        grad[j] = 0.0
    a = p[6:9]
    t = p[0:3]
    c0, c1, c2 = camera_local(t[0], t[1], t[2], R)
    total = 0.0
    diff = np.zeros(3)
    loc = np.zeros(3)
    q = np.zeros(3)
    gy = np.zeros(3)
    ga = np.zeros(3)
    for i in range(n):
        for c in range(3):
            diff[c] = pts[i, c] - t[c]
        for c in range(3):
            loc[c] = R[0, c] * diff[0] + R[1, c] * diff[1] + R[2, c] * diff[2]
            q[c] = abs(loc[c]) - a[c]
        # Eq. 2
        d2 = 0.0
        kmin = 0
        mmin = 1e300
        for c in range(3):
            if q[c] > 0:
                d2 += q[c] * q[c]
            if -q[c] < mmin:
                mmin = -q[c]
                kmin = c
        inside = mmin > 0
        if inside:
            d2 += mmin * mmin
        best = d2
        side_k = -1
        side_s = 0.0
        e0, e1, e2 = _excess_sq(q)
        occ_in, ax_in, sg_in, d_in, occ_out, ax_out, sg_out, d_out = occluding_sides(
            loc[0], loc[1], loc[2], a[0], a[1], a[2], c0, c1, c2, e0, e1, e2
        )
        if occ_in and d_in > best:  # the farthest occluding side, if farther than the box itself
            best, side_k, side_s = d_in, ax_in, sg_in
        if occ_out and d_out > best:
            best, side_k, side_s = d_out, ax_out, sg_out
        total += best
        for c in range(3):
            gy[c] = 0.0
            ga[c] = 0.0
        if side_k < 0:
            for c in range(3):
                if q[c] > 0:
                    sg = 1.0 if loc[c] >= 0 else -1.0
                    gy[c] = 2.0 * q[c] * sg
                    ga[c] = -2.0 * q[c]
            if inside:
                sg = 1.0 if loc[kmin] >= 0 else -1.0
                gy[kmin] = -2.0 * mmin * sg
                ga[kmin] = 2.0 * mmin
        else:
            dn = loc[side_k] - side_s * a[side_k]
            gy[side_k] = 2.0 * dn
            ga[side_k] = -2.0 * side_s * dn
            for c in range(3):
                if c != side_k and q[c] > 0:
                    sg = 1.0 if loc[c] >= 0 else -1.0
                    gy[c] = 2.0 * q[c] * sg
                    ga[c] = -2.0 * q[c]
        for c in range(3):
            grad[c] -= R[c, 0] * gy[0] + R[c, 1] * gy[1] + R[c, 2] * gy[2]
            grad[6 + c] += ga[c]
        for k in range(3):
            acc = 0.0
            for c in range(3):
                acc += gy[c] * (dR[k, 0, c] * diff[0] + dR[k, 1, c] * diff[1] + dR[k, 2, c] * diff[2])
            grad[3 + k] += acc
    for j in range(9):
        grad[j] /= n
    return total / n


@njit(cache=True)
def refine_adam(pts, init, a_min, a_max, lr, iters):
    """Adam on the mean d_oa^2 of points (N, 3) from init (9,) = (centre, axis-angle, half-sizes);
    returns the best iterate (9,)."""
    b1, b2 = 0.9, 0.999  # Adam betas, as in adam_update
    p = init.copy()
    out = init.copy()
    m = np.zeros(9)
    v = np.zeros(9)
    grad = np.zeros(9)
    R = np.zeros((3, 3))
    dR = np.zeros((3, 3, 3))
    best = 1e300
    for it in range(iters + 1):
        th2 = rodrigues(p[3], p[4], p[5], R)
        rodrigues_derivatives(p[3:6], R, th2, dR)
        loss = _oa_objective_and_grad(pts, p, R, dR, grad)
        if loss < best:
            best = loss
            out[:] = p
        if it == iters:
            break
        t = it + 1
        c1 = 1.0 - b1**t
        c2 = 1.0 - b2**t
        adam_update(p, m, v, grad, lr, c1, c2, a_min, a_max)
    return out


@njit(cache=True)
def oa_objective_and_grad(pts, p):
    """Test hook: mean d_oa^2 of points (N, 3) to the cuboid p (9,) and its gradient."""
    R = np.zeros((3, 3))
    dR = np.zeros((3, 3, 3))
    grad = np.zeros(9)
    th2 = rodrigues(p[3], p[4], p[5], R)
    rodrigues_derivatives(p[3:6], R, th2, dR)
    f = _oa_objective_and_grad(pts, p, R, dR, grad)
    return f, grad

"""CPU fast path of the numerical solver: PCA-initialised Adam with analytic gradients, one fused loop
per hypothesis (numba), parallel over hypotheses.

Same objective, parametrisation (centre, axis-angle, half-sizes), update rule and best-iterate rule as
the torch reference in :mod:`cuboidcli.solvers.numerical`; tests compare the two. Rodrigues' formula and
the Adam step are the ones the winner's refinement runs too (:mod:`cuboidcli.geometry.adam`); the
rotation gradient here goes through the right Jacobian of SO(3).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit, prange

from cuboidcli.geometry.adam import adam_update, rodrigues
from cuboidcli.geometry.inlier import to_local


@njit(cache=True)
def _right_jacobian(r0, r1, r2, th2, J):
    """Right Jacobian of SO(3) at r, J = I - (1 - cos t)/t^2 [r]x + (t - sin t)/t^3 [r]x^2, into J (3, 3):
    R(r + dr) = R(r) exp([J dr]x) to first order."""
    if th2 < 1e-12:
        b = 0.5 - th2 / 24.0
        c = 1.0 / 6.0 - th2 / 120.0
    else:
        th = math.sqrt(th2)
        b = (1.0 - math.cos(th)) / th2
        c = (th - math.sin(th)) / (th2 * th)
    # [r]x^2 = r r^T - th2 I
    J[0, 0] = 1.0 + c * (r0 * r0 - th2)
    J[0, 1] = b * r2 + c * r0 * r1
    J[0, 2] = -b * r1 + c * r0 * r2
    J[1, 0] = -b * r2 + c * r1 * r0
    J[1, 1] = 1.0 + c * (r1 * r1 - th2)
    J[1, 2] = b * r0 + c * r1 * r2
    J[2, 0] = b * r1 + c * r2 * r0
    J[2, 1] = -b * r0 + c * r2 * r1
    J[2, 2] = 1.0 + c * (r2 * r2 - th2)


@njit(cache=True, inline="always")
def _axis_grad(coord, a):
    """Eq. 2 terms of one local coordinate: (excess q = |coord| - a, sign of coord)."""
    return abs(coord) - a, (1.0 if coord >= 0 else -1.0)


@njit(cache=True)
def _objective_and_grad(pts, p, R, dR, grad):
    """F = sum_i d(h, y_i)^2 * (a_x + a_y + a_z) and its gradient w.r.t. p = (t, r, a).

    Written with scalars only (no per-call allocations): this is the innermost loop of the solver.
    """
    n = pts.shape[0]
    t0, t1, t2 = p[0], p[1], p[2]
    a0, a1, a2 = p[6], p[7], p[8]
    asum = a0 + a1 + a2
    dsum = 0.0
    gt0 = gt1 = gt2 = 0.0
    gr0 = gr1 = gr2 = 0.0
    ga0 = ga1 = ga2 = 0.0
    for i in range(n):
        x0 = pts[i, 0] - t0
        x1 = pts[i, 1] - t1
        x2 = pts[i, 2] - t2
        l0, l1, l2 = to_local(x0, x1, x2, R)
        q0, s0 = _axis_grad(l0, a0)
        q1, s1 = _axis_grad(l1, a1)
        q2, s2 = _axis_grad(l2, a2)
        g0 = g1 = g2 = 0.0
        d2 = 0.0
        if q0 > 0:
            d2 += q0 * q0
            g0 = 2.0 * q0 * s0
            ga0 -= 2.0 * q0 * asum
        if q1 > 0:
            d2 += q1 * q1
            g1 = 2.0 * q1 * s1
            ga1 -= 2.0 * q1 * asum
        if q2 > 0:
            d2 += q2 * q2
            g2 = 2.0 * q2 * s2
            ga2 -= 2.0 * q2 * asum
        if q0 < 0 and q1 < 0 and q2 < 0:
            # inside: distance to the nearest face (first minimum, as torch's min)
            m = -q0
            k = 0
            if -q1 < m:
                m = -q1
                k = 1
            if -q2 < m:
                m = -q2
                k = 2
            d2 += m * m
            if k == 0:
                g0 = -2.0 * m * s0
                ga0 += 2.0 * m * asum
            elif k == 1:
                g1 = -2.0 * m * s1
                ga1 += 2.0 * m * asum
            else:
                g2 = -2.0 * m * s2
                ga2 += 2.0 * m * asum
        dsum += d2
        if g0 == 0.0 and g1 == 0.0 and g2 == 0.0:
            continue
        # loc = R^T (y - t): dF/dt = -R g asum; dF/dr_k = g . (dR_k^T (y - t)) asum
        gt0 -= R[0, 0] * g0 + R[0, 1] * g1 + R[0, 2] * g2
        gt1 -= R[1, 0] * g0 + R[1, 1] * g1 + R[1, 2] * g2
        gt2 -= R[2, 0] * g0 + R[2, 1] * g1 + R[2, 2] * g2
        # rotation: with R' = R exp([d]x), loc' = loc + loc x d, so dF/dd = sum g x loc (right Jacobian below)
        gr0 += g1 * l2 - g2 * l1
        gr1 += g2 * l0 - g0 * l2
        gr2 += g0 * l1 - g1 * l0
    grad[0] = gt0 * asum
    grad[1] = gt1 * asum
    grad[2] = gt2 * asum
    # dF/dr = J_r(r)^T dF/dd, stored in dR[0] by the caller
    grad[3] = (dR[0, 0, 0] * gr0 + dR[0, 1, 0] * gr1 + dR[0, 2, 0] * gr2) * asum
    grad[4] = (dR[0, 0, 1] * gr0 + dR[0, 1, 1] * gr1 + dR[0, 2, 1] * gr2) * asum
    grad[5] = (dR[0, 0, 2] * gr0 + dR[0, 1, 2] * gr1 + dR[0, 2, 2] * gr2) * asum
    grad[6] = ga0 + dsum
    grad[7] = ga1 + dsum
    grad[8] = ga2 + dsum
    return dsum * asum


@njit(parallel=True, cache=True)
def adam_solve(pts, init, a_min, a_max, lr, iters, out, rot_dof=3):
    """pts (H, C, 3) float64; init (H, 9) = (centre, axis-angle, half-sizes); best iterates go to out.

    ``rot_dof``: 3 = free rotation; 1 = about z only (the axis-angle's x and y stay as given: a yaw when
    they are 0 and z is up); 0 = the rotation stays as given."""
    b1, b2 = 0.9, 0.999  # Adam betas, as in adam_update
    for h in prange(pts.shape[0]):
        p = init[h].copy()
        m = np.zeros(9)
        v = np.zeros(9)
        grad = np.zeros(9)
        R = np.zeros((3, 3))
        dR = np.zeros((3, 3, 3))
        best = 1e300
        p1 = 1.0
        p2 = 1.0
        for it in range(iters + 1):
            th2 = rodrigues(p[3], p[4], p[5], R)
            _right_jacobian(p[3], p[4], p[5], th2, dR[0])
            loss = _objective_and_grad(pts[h], p, R, dR, grad)
            if loss < best:
                best = loss
                out[h, :] = p
            if it == iters:
                break
            p1 *= b1
            p2 *= b2
            c1 = 1.0 - p1
            c2 = 1.0 - p2
            for j in range(3, 6 - rot_dof):
                grad[j] = 0.0
            adam_update(p, m, v, grad, lr, c1, c2, a_min, a_max)


@njit(cache=True, parallel=True)
def rotation_matrices(axis_angles, out):
    """Rodrigues' formula for each row of ``axis_angles`` (H, 3) into ``out`` (H, 3, 3)."""
    for h in prange(axis_angles.shape[0]):
        rodrigues(axis_angles[h, 0], axis_angles[h, 1], axis_angles[h, 2], out[h])


@njit(cache=True)
def objective_and_grad(pts, p):
    """Test hook: F and dF/dp for one minimal set (C, 3) and parameters p (9,)."""
    R = np.zeros((3, 3))
    dR = np.zeros((3, 3, 3))
    grad = np.zeros(9)
    th2 = rodrigues(p[3], p[4], p[5], R)
    _right_jacobian(p[3], p[4], p[5], th2, dR[0])
    f = _objective_and_grad(pts, p, R, dR, grad)
    return f, grad

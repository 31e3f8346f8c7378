"""The occlusion-aware inlier function f_OAI of one point and one cuboid, as numba device functions.

f_I(d^2) = sigmoid(beta (1 - d^2 / tau)) of the squared point-to-side distance, and for a point hidden behind
a side (seen through the box) the leaky penalty f_O of that side: f_IO = f_I - f_O (paper Sec. 3.5). What
makes it cheap (NOTES.md): max_i f_I(d_i^2) = f_I(d^2) of the point-to-cuboid distance; a convex box meets
the line of sight in one interval, so a slab test finds the at most two occluding sides; f_I underflows
far from the box, so pairs beyond ``cutoff`` (:func:`inlier_params`) that are not occluded get value 0.

Every fused loop builds on these: the hypothesis scoring and the values of :mod:`.fused`, the room
scoring of :mod:`.room` and the numerical solver's refinement (:mod:`cuboidcli.solvers.adam_fused`, which
shares :func:`camera_local` and :func:`occluding_sides`).
"""

from __future__ import annotations

import math

from numba import njit

from cuboidcli.geometry.arrays import namespace

INLIER_CUT = 0.5
"""The inlier value that makes a point an inlier: f_I(d^2) = 0.5 exactly at d^2 = tau, so a point whose
value f_OAI for a cuboid is at least this lies within sqrt(tau) of its surface and is not hidden by it. A
state below it (``state < INLIER_CUT``) marks a point no selected cuboid explains yet."""


def combine(new, old):
    """f_OAI of a set joined with a new cuboid, from both values (numpy arrays or tensors alike): the
    minimum if negative, else the maximum."""
    xp = namespace(new)
    lo = xp.minimum(new, old)
    return xp.where(lo < 0, lo, xp.maximum(new, old))


@njit(cache=True, inline="always")
def f_inlier(d2, beta, inv_tau):
    return 1.0 / (1.0 + math.exp(-beta * (1.0 - d2 * inv_tau)))


@njit(cache=True, inline="always")
def _fo(d2, beta, inv_tau, tau_c, slope, offset):
    if d2 < tau_c:
        return 1.0 - f_inlier(d2, beta, inv_tau)
    return slope * d2 + offset


@njit(cache=True)
def slab_occlusion(l0, l1, l2, a0, a1, a2, c0, c1, c2):
    """Sides of the box crossing the segment from a point (local l) to the camera (local c), lambda in (0, 1).

    A convex box meets the segment in one interval [lam_in, lam_out]; the entry side occludes if
    0 < lam_in < 1 and the exit side if 0 < lam_out < 1. Returns (occ_in, axis_in, sign_in, occ_out,
    axis_out, sign_out). Equivalent to the paper's per-plane test (Eq. 6) except on measure-zero edge hits.
    """
    lam_in = -1e300
    lam_out = 1e300
    ax_in = -1
    sg_in = 0.0
    ax_out = -1
    sg_out = 0.0
    for k in range(3):
        if k == 0:
            lk, vk, ak = l0, c0 - l0, a0
        elif k == 1:
            lk, vk, ak = l1, c1 - l1, a1
        else:
            lk, vk, ak = l2, c2 - l2, a2
        if abs(vk) < 1e-12:
            if abs(lk) > ak:
                return False, -1, 0.0, False, -1, 0.0
            continue
        inv = 1.0 / vk
        t_pos = (ak - lk) * inv
        t_neg = (-ak - lk) * inv
        if t_pos < t_neg:
            t_near, s_near, t_far, s_far = t_pos, 1.0, t_neg, -1.0
        else:
            t_near, s_near, t_far, s_far = t_neg, -1.0, t_pos, 1.0
        if t_near > lam_in:
            lam_in, ax_in, sg_in = t_near, k, s_near
        if t_far < lam_out:
            lam_out, ax_out, sg_out = t_far, k, s_far
    hit = lam_in < lam_out
    return hit and 0.0 < lam_in < 1.0, ax_in, sg_in, hit and 0.0 < lam_out < 1.0, ax_out, sg_out


@njit(cache=True)
def pair_value(l0, l1, l2, a0, a1, a2, c0, c1, c2, beta, inv_tau, tau_c, slope, offset, cutoff, oai):
    """f_OAI(y, {h}) of one point (local coords l) and one cuboid (half-sizes a, camera at c)."""
    q0 = abs(l0) - a0
    q1 = abs(l1) - a1
    q2 = abs(l2) - a2
    e0 = q0 * q0 if q0 > 0 else 0.0
    e1 = q1 * q1 if q1 > 0 else 0.0
    e2 = q2 * q2 if q2 > 0 else 0.0
    ex = e0 + e1 + e2
    m = min(-q0, min(-q1, -q2))
    d2 = ex + (m * m if m > 0 else 0.0)
    if not oai:
        return f_inlier(d2, beta, inv_tau) if d2 < cutoff else 0.0
    occ_in, ax_in, sg_in, d_in, occ_out, ax_out, sg_out, d_out = occluding_sides(
        l0, l1, l2, a0, a1, a2, c0, c1, c2, e0, e1, e2
    )
    if not (occ_in or occ_out):
        return f_inlier(d2, beta, inv_tau) if d2 < cutoff else 0.0
    # Occluded by one or two sides. f_IO = f_I - f_O of an occluding side is negative exactly when its
    # d_i^2 > tau, and then the point's value is the minimum over the occluding sides (non-occluding sides
    # have f_IO = f_I > 0). Only when every occluding side is within tau are all six sides needed.
    vmin = 1e300
    if occ_in:
        vmin = min(vmin, occluding_value(d_in, beta, inv_tau, tau_c, slope, offset, cutoff))
    if occ_out:
        vmin = min(vmin, occluding_value(d_out, beta, inv_tau, tau_c, slope, offset, cutoff))
    if vmin < 0:
        return vmin
    vmax = -1e300
    for side in range(6):
        k = side // 2
        s = 1.0 if side % 2 == 0 else -1.0
        ds = _side_d2(k, s, l0, l1, l2, a0, a1, a2, e0, e1, e2)
        f = f_inlier(ds, beta, inv_tau)
        if (occ_in and k == ax_in and s == sg_in) or (occ_out and k == ax_out and s == sg_out):
            f -= _fo(ds, beta, inv_tau, tau_c, slope, offset)
        vmin = min(vmin, f)
        vmax = max(vmax, f)
    return vmin if vmin < 0 else vmax


@njit(cache=True, inline="always")
def occluding_value(ds, beta, inv_tau, tau_c, slope, offset, cutoff):
    """f_IO = f_I - f_O of an occluding side at squared distance ds."""
    if ds >= cutoff:
        return -(slope * ds + offset)  # f_I underflows; f_O is on its linear branch (cutoff > tau_c)
    return f_inlier(ds, beta, inv_tau) - _fo(ds, beta, inv_tau, tau_c, slope, offset)


@njit(cache=True, inline="always")
def occluding_sides(l0, l1, l2, a0, a1, a2, c0, c1, c2, e0, e1, e2):
    """The sides of a box on a point's line of sight (:func:`slab_occlusion`) and the point's squared
    distance to each (:func:`_side_d2`; e = the squared positive excess of the local coordinates l over
    the half-sizes a, per axis, 0 where l is within a).

    Returns (occ_in, axis_in, sign_in, d2_in, occ_out, axis_out, sign_out, d2_out); a d2 is 0 where its
    side does not occlude. The values (:func:`pair_value`) and the occlusion-aware distance of the
    refinement (:mod:`cuboidcli.solvers.adam_fused`) both start from these."""
    occ_in, ax_in, sg_in, occ_out, ax_out, sg_out = slab_occlusion(l0, l1, l2, a0, a1, a2, c0, c1, c2)
    d_in = _side_d2(ax_in, sg_in, l0, l1, l2, a0, a1, a2, e0, e1, e2) if occ_in else 0.0
    d_out = _side_d2(ax_out, sg_out, l0, l1, l2, a0, a1, a2, e0, e1, e2) if occ_out else 0.0
    return occ_in, ax_in, sg_in, d_in, occ_out, ax_out, sg_out, d_out


@njit(cache=True, inline="always")
def _side_d2(k, s, l0, l1, l2, a0, a1, a2, e0, e1, e2):
    """Squared distance to side (axis k, sign s): normal offset^2 + tangential excess^2."""
    if k == 0:
        dn = l0 - s * a0
        return dn * dn + e1 + e2
    if k == 1:
        dn = l1 - s * a1
        return dn * dn + e0 + e2
    dn = l2 - s * a2
    return dn * dn + e0 + e1


def leaky_constants(tau: float, beta: float, tau_c: float) -> tuple[float, float]:
    """Slope m = -f_I'(tau_c) and offset b = 1 - f_I(tau_c) - m tau_c of the leaky occlusion penalty."""
    x = beta * (1.0 - tau_c / tau)
    # sigmoid(x) without overflow for the large tau_c of the training schedule (x << 0)
    fi_c = 1.0 / (1.0 + math.exp(-x)) if x >= 0 else math.exp(x) / (1.0 + math.exp(x))
    slope = beta / tau * fi_c * (1.0 - fi_c)
    return slope, 1.0 - fi_c - slope * tau_c


@njit(cache=True, inline="always")
def to_local(x, y, z, R):
    """An offset (x, y, z) from a cuboid's centre in the cuboid's frame: R^T (x, y, z)."""
    return (
        R[0, 0] * x + R[1, 0] * y + R[2, 0] * z,
        R[0, 1] * x + R[1, 1] * y + R[2, 1] * z,
        R[0, 2] * x + R[1, 2] * y + R[2, 2] * z,
    )


@njit(cache=True, inline="always")
def camera_local(t0, t1, t2, R):
    """The camera centre (the origin) in a cuboid's frame: -R^T t."""
    l0, l1, l2 = to_local(t0, t1, t2, R)
    return -l0, -l1, -l2


def inlier_params(tau: float, beta: float, tau_c: float, occlusion_aware: bool) -> tuple:
    """(beta, 1/tau, tau_c, slope, offset, cutoff, oai): the scalar arguments every kernel takes."""
    slope, offset = leaky_constants(tau, beta, tau_c)
    cutoff = tau * (1.0 + 40.0 / beta)  # f_I < 1e-17 beyond: treated as 0
    return float(beta), 1.0 / tau, float(tau_c), slope, offset, cutoff, bool(occlusion_aware)

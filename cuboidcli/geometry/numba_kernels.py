"""Numba building blocks of the box geometry, shared by the fused CPU loops of the scorer
(:mod:`cuboidcli.fitting.fused`) and of the numerical solver (:mod:`cuboidcli.solvers.adam_fused`): the
camera centre in a cuboid's frame and the slab test for the sides that hide a point from the camera. The
torch versions, batched and differentiable, are in :mod:`cuboidcli.geometry.kernels`.
"""

from __future__ import annotations

from numba import njit


@njit(cache=True, inline="always")
def camera_local(t0, t1, t2, R):
    """The camera centre (the origin) in a cuboid's frame: -R^T t."""
    return (
        -(R[0, 0] * t0 + R[1, 0] * t1 + R[2, 0] * t2),
        -(R[0, 1] * t0 + R[1, 1] * t1 + R[2, 1] * t2),
        -(R[0, 2] * t0 + R[1, 2] * t1 + R[2, 2] * t2),
    )


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

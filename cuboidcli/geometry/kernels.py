"""Point-to-cuboid geometry and occlusion-aware inlier values (paper Sec. 3.1 and 3.2.4), in torch.

Every function is batched and differentiable, works in float32 and float64 on CPU and CUDA. Shapes:
points ``(N, 3)``; hypotheses ``centers (H, 3)``, ``half_sizes (H, 3)``, ``rotations (H, 3, 3)``;
per-pair results ``(H, N)``; per-side results ``(H, N, 6)``. The camera centre is the origin.
Sides are ordered (+x, -x, +y, -y, +z, -z) in the cuboid's local frame.

These kernels are the reference implementation (used for training, metrics and on CUDA). Inference on
the CPU scores hypotheses with the fused loop in :mod:`cuboidcli.geometry.fused`, tested against these.
"""

from __future__ import annotations

import torch
from torch import Tensor

# INLIER_CUT and combine are shared with the numpy code of a fit, which must not import torch: defined once,
# in .inlier, and offered here with the torch kernels
from cuboidcli.geometry.inlier import INLIER_CUT, combine  # noqa: F401 - re-exported

SIDE_AXIS = (0, 0, 1, 1, 2, 2)
SIDE_SIGN = (1.0, -1.0, 1.0, -1.0, 1.0, -1.0)


def to_local(points: Tensor, centers: Tensor, rotations: Tensor) -> Tensor:
    """Points (N, 3) into each cuboid's frame, y_hat = R^T (y - t) (Eq. 1): (H, N, 3)."""
    return torch.einsum("hnk,hkc->hnc", points[None] - centers[:, None, :], rotations)


def camera_local(centers: Tensor, rotations: Tensor) -> Tensor:
    """Camera centre in each cuboid's frame, c_hat = -R^T t: (H, 3)."""
    return -torch.einsum("hk,hkc->hc", centers, rotations)


def cuboid_sq_distance(local: Tensor, half_sizes: Tensor) -> Tensor:
    """Squared point-to-cuboid-surface distance d(h, y)^2 (Eq. 2), for points inside and outside: (H, N)."""
    a = half_sizes[:, None, :]
    q = local.abs() - a
    outside = q.clamp_min(0).square().sum(-1)
    inside = (-q).min(-1).values.clamp_min(0).square()
    return outside + inside


def side_sq_distances(local: Tensor, half_sizes: Tensor) -> Tensor:
    """Squared distance to each of the six side rectangles, d^P_i(h, y)^2 (Sec. 3.1): (H, N, 6)."""
    a = half_sizes[:, None, :]
    out = (local.abs() - a).clamp_min(0).square()  # (H, N, 3) per-axis excess
    sides = []
    for axis, sign in zip(SIDE_AXIS, SIDE_SIGN, strict=True):
        normal = (local[..., axis] - sign * a[..., axis]).square()
        tangential = out.sum(-1) - out[..., axis]
        sides.append(normal + tangential)
    return torch.stack(sides, -1)


def occlusion_indicator(local: Tensor, half_sizes: Tensor, cam_local: Tensor) -> Tensor:
    """chi_o (Eq. 6): does side i lie on the line of sight between the point and the camera? (H, N, 6) bool.

    For side i with plane x_c = s * a_c the segment y_hat + lambda (c_hat - y_hat) meets the plane at
    lambda = (s a_c - y_hat_c) / (c_hat_c - y_hat_c); the side occludes when 0 < lambda < 1 and the
    intersection lies on the side's rectangle. The paper tests lambda > 0 on the infinite line; we stop at
    the camera (lambda < 1) because a surface behind the camera cannot hide anything.
    """
    a = half_sizes[:, None, :]
    v = cam_local[:, None, :] - local  # (H, N, 3)
    chis = []
    for axis, sign in zip(SIDE_AXIS, SIDE_SIGN, strict=True):
        vc = v[..., axis]
        ok = vc.abs() > 1e-12
        lam = (sign * a[..., axis] - local[..., axis]) / torch.where(ok, vc, torch.ones_like(vc))
        hit = local + lam[..., None] * v
        inside = torch.ones_like(ok)
        for k in range(3):
            if k != axis:
                inside = inside & (hit[..., k].abs() <= a[..., k])
        chis.append(ok & (lam > 0) & (lam < 1) & inside)
    return torch.stack(chis, -1)


def inlier_fn(d_sq: Tensor, tau: float, beta: float) -> Tensor:
    """Soft inlier f_I(d) = 1 - sigmoid(beta d / tau - beta) of a squared distance (Sec. 3.2.4)."""
    return torch.sigmoid(beta * (1.0 - d_sq / tau))


def occlusion_fn(d_sq: Tensor, tau: float, beta: float, tau_c: float) -> Tensor:
    """Leaky occlusion penalty f_O (Sec. 3.2.4): 1 - f_I below tau_c, linear with matching slope above."""
    fi_c = torch.sigmoid(torch.tensor(beta * (1.0 - tau_c / tau), dtype=torch.float64)).item()
    slope = beta / tau * fi_c * (1.0 - fi_c)  # m = -f_I'(tau_c)
    offset = 1.0 - fi_c - slope * tau_c  # b
    return torch.where(d_sq < tau_c, 1.0 - inlier_fn(d_sq, tau, beta), slope * d_sq + offset)


def side_inlier_occlusion(points, centers, half_sizes, rotations, tau, beta, tau_c) -> Tensor:
    """f_IO(y, h, i) = f_I(d_i^2) - chi_i f_O(d_i^2) for every side: (H, N, 6)."""
    local = to_local(points, centers, rotations)
    d_sq = side_sq_distances(local, half_sizes)
    chi = occlusion_indicator(local, half_sizes, camera_local(centers, rotations))
    return inlier_fn(d_sq, tau, beta) - chi.to(d_sq.dtype) * occlusion_fn(d_sq, tau, beta, tau_c)


def reduce_oai(f_io: Tensor, dims) -> Tensor:
    """f_OAI: the minimum over sides if it is negative (occluded), else the maximum (Sec. 3.2.4)."""
    lo = f_io.amin(dim=dims)
    hi = f_io.amax(dim=dims)
    return torch.where(lo < 0, lo, hi)


def oai_per_cuboid(points, centers, half_sizes, rotations, tau, beta, tau_c) -> Tensor:
    """f_OAI(y, {h}) of each cuboid on its own: (H, N)."""
    return reduce_oai(side_inlier_occlusion(points, centers, half_sizes, rotations, tau, beta, tau_c), -1)


def oai_of_set(points, centers, half_sizes, rotations, tau, beta, tau_c) -> Tensor:
    """f_OAI(y, M) of a cuboid set M (the state): (N,). Zero for an empty set."""
    if centers.shape[0] == 0:
        return torch.zeros(points.shape[0], dtype=points.dtype, device=points.device)
    return reduce_oai(side_inlier_occlusion(points, centers, half_sizes, rotations, tau, beta, tau_c), (0, 2))


def oa_sq_distance(points, centers, half_sizes, rotations) -> Tensor:
    """Squared occlusion-aware distance d_oa(M, y)^2 (Sec. 3.1): (N,).

    max(min over cuboids of d^2, max over cuboids and sides of chi * d_i^2). Infinite for an empty set.
    """
    if centers.shape[0] == 0:
        return torch.full((points.shape[0],), float("inf"), dtype=points.dtype, device=points.device)
    local = to_local(points, centers, rotations)
    d_sq = cuboid_sq_distance(local, half_sizes).amin(0)
    chi = occlusion_indicator(local, half_sizes, camera_local(centers, rotations))
    occ = (side_sq_distances(local, half_sizes) * chi.to(points.dtype)).amax(dim=(0, 2))
    return torch.maximum(d_sq, occ)

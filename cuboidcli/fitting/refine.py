"""Refining the selected cuboid on all the points it explains ("refine the winner"): :func:`refine_cuboid`
(torch, any device) and :func:`refine_cuboid_fused` (numba, CPU), which the backends run
(:meth:`cuboidcli.fitting.backend.ScoringBackend.refine`).

A minimal set fixes a cuboid only up to the softness of the inlier function: a thin slab whose far face
carries the points scores the same as one whose near face does (f_IO of the occluding near face stays
positive while it is within sqrt(tau) of the point), yet its occlusion-aware distance is off by up to
sqrt(tau) ~ 6 cm. Refinement minimises the mean squared occlusion-aware distance d_oa(h, y)^2 (Sec. 3.1)
of the winner's inliers with Adam, in the spirit of the paper's optional EM refinement (appendix); the
estimator keeps the refined cuboid only if its inlier-count gain holds (``FitConfig.refine_keep``).
Iterations and learning rate are ``FitConfig.refine_iters`` and ``FitConfig.refine_lr``.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cuboidcli.fitting.config import FitConfig
from cuboidcli.geometry.rotations import axis_angle_to_matrix, matrix_to_axis_angle

if TYPE_CHECKING:
    from torch import Tensor


def refine_cuboid_fused(
    points: np.ndarray,
    center,
    half,
    rotation,
    a_min: float,
    a_max: float,
    iters: int = FitConfig.refine_iters,
    lr: float = FitConfig.refine_lr,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """CPU fast path of :func:`refine_cuboid` (numba, analytic gradient); numpy in, numpy out."""
    from cuboidcli.geometry.adam import refine_adam

    r = matrix_to_axis_angle(np.asarray(rotation, dtype=np.float64))
    init = np.concatenate([np.asarray(center, np.float64), r, np.asarray(half, np.float64)])
    best = refine_adam(np.ascontiguousarray(points, np.float64), init, a_min, a_max, lr, iters)
    R = axis_angle_to_matrix(best[3:6].copy())
    return best[:3], best[6:], R


def refine_cuboid(
    points: Tensor,
    center: Tensor,
    half: Tensor,
    rotation: Tensor,
    a_min: float,
    a_max: float,
    iters: int = FitConfig.refine_iters,
    lr: float = FitConfig.refine_lr,
) -> tuple[Tensor, Tensor, Tensor]:
    """points (N, 3) inliers; center (3,), half (3,), rotation (3, 3) -> refined (center, half, R): the best
    of ``iters`` Adam steps (learning rate ``lr``), half-sizes kept in [a_min, a_max]."""
    import torch

    from cuboidcli.geometry import kernels as K

    pts = points.double()
    c = center.double().clone().requires_grad_(True)
    r = matrix_to_axis_angle(rotation.double()).clone().requires_grad_(True)
    a = half.double().clone().requires_grad_(True)
    opt = torch.optim.Adam([c, r, a], lr=lr)
    best = (float("inf"), center.double(), half.double(), rotation.double())
    with torch.enable_grad():
        for it in range(iters + 1):
            R = axis_angle_to_matrix(r)[None]
            loss = K.oa_sq_distance(pts, c[None], a[None], R).mean()
            if loss.item() < best[0]:
                best = (loss.item(), c.detach().clone(), a.detach().clone(), R[0].detach().clone())
            if it == iters:
                break
            opt.zero_grad(set_to_none=True)
            loss.backward()
            opt.step()
            with torch.no_grad():
                a.clamp_(a_min, a_max)
    _, cb, ab, Rb = best
    return cb.to(center.dtype), ab.to(half.dtype), Rb.to(rotation.dtype)

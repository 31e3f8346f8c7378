"""Scoring hypotheses by their inlier-count gain: exact, with pruning, or with the approximate fast path.

The CPU path uses the fused numba loop (:mod:`cuboidcli.geometry.fused`); other devices use the torch
reference kernels in chunks of hypotheses.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from cuboidcli.geometry import kernels as K


@dataclass(frozen=True)
class ScoreParams:
    tau: float
    beta: float
    tau_c: float
    occlusion_aware: bool = True


def values_torch(points: Tensor, centers, half_sizes, rotations, sp: ScoreParams) -> Tensor:
    """f_OAI(y, {h}) per hypothesis (H, N), or the plain soft inlier f_I(d^2) without OAI."""
    if sp.occlusion_aware:
        return K.oai_per_cuboid(points, centers, half_sizes, rotations, sp.tau, sp.beta, sp.tau_c)
    local = K.to_local(points, centers, rotations)
    return K.inlier_fn(K.cuboid_sq_distance(local, half_sizes), sp.tau, sp.beta)


def gains_torch(
    points: Tensor, centers, half_sizes, rotations, state: Tensor, sp: ScoreParams, chunk: int = 64
) -> Tensor:
    """Reference gains (H,): sum over points of combine(value, state) - state."""
    out = []
    for s in range(0, centers.shape[0], chunk):
        v = values_torch(
            points, centers[s : s + chunk], half_sizes[s : s + chunk], rotations[s : s + chunk], sp
        )
        out.append((K.combine(v, state[None]) - state[None]).sum(1))
    return torch.cat(out) if out else torch.zeros(0, dtype=points.dtype, device=points.device)


def gains_cpu(
    points: np.ndarray,
    centers,
    half_sizes,
    rotations,
    state: np.ndarray,
    sp: ScoreParams,
    prune_below: float = -np.inf,
) -> np.ndarray:
    from cuboidcli.geometry.fused import score_gains

    return score_gains(
        points,
        centers,
        half_sizes,
        rotations,
        state,
        sp.tau,
        sp.beta,
        sp.tau_c,
        sp.occlusion_aware,
        prune_below,
    )


def select_best(
    points: Tensor,
    centers: Tensor,
    half_sizes: Tensor,
    rotations: Tensor,
    state: Tensor,
    sp: ScoreParams,
    generator: torch.Generator,
    prescore_points: int = 0,
    rescore_top: int = 64,
) -> tuple[int, float, Tensor]:
    """Index and exact gain of the best hypothesis, plus the gains vector (-inf where not computed).

    prescore_points == 0 (default) is exact: a cheap pass on a random eighth of the points nominates 16
    candidates whose exact gains give a threshold, then every hypothesis is scored on all points with
    provable pruning below that threshold, so the selected hypothesis is the true argmax.
    prescore_points > 0 is the approximate fast path: all hypotheses are scored on that many random points
    and only the best ``rescore_top`` are scored on all points.
    """
    n = points.shape[0]
    if points.device.type != "cpu":
        g = gains_torch(points, centers, half_sizes, rotations, state, sp)  # exact on GPUs
        best = int(torch.argmax(g))
        return best, float(g[best]), g.cpu().double()
    P = points.double().numpy()
    C, A, R = (x.double().numpy() for x in (centers, half_sizes, rotations))
    S = state.double().numpy()
    n_sub = prescore_points if prescore_points > 0 else max(n // 8, 1)
    if n_sub < n:
        sub = torch.randperm(n, generator=generator)[:n_sub].numpy()
        g_sub = gains_cpu(P[sub], C, A, R, S[sub], sp)
        k = rescore_top if prescore_points > 0 else 16
        top = np.argsort(-g_sub, kind="stable")[:k]
        g_top = gains_cpu(P, C[top], A[top], R[top], S, sp)
        if prescore_points > 0:
            g = np.full(C.shape[0], -np.inf)
            g[top] = g_top
        else:
            g = gains_cpu(P, C, A, R, S, sp, prune_below=float(g_top.max()) - 1e-6)  # margin for rounding
    else:
        g = gains_cpu(P, C, A, R, S, sp)
    best = int(np.argmax(g))
    return best, float(g[best]), torch.from_numpy(g)

"""The inlier function's parameters (:class:`ScoreParams`) and the kernels of values and gains the
backends (:mod:`cuboidcli.fitting.backend`) run: the torch reference kernels (:func:`values_torch`,
:func:`gains_torch`, any device, in chunks of hypotheses) and the fused numba loop (:func:`gains_cpu`,
numpy on the CPU)."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

if TYPE_CHECKING:
    from torch import Tensor


@dataclass(frozen=True)
class ScoreParams:
    """The inlier function's parameters: tau (m^2), beta, the occlusion threshold tau_c (m^2), and whether
    inliers are counted occlusion-aware (f_OAI) or plainly (f_I)."""

    tau: float = 0.004
    beta: float = 5.0
    tau_c: float = 0.008
    occlusion_aware: bool = True

    @classmethod
    def of(cls, settings) -> ScoreParams:
        """The parameters of a FitConfig, or of a result's ``settings`` dict (its ``tau_sq_m2``, ``beta``,
        ``tau_c_sq_m2`` (None: 2 tau) and ``occlusion_aware``; a key missing: the default)."""
        get = settings.get if isinstance(settings, dict) else lambda k, d=None: getattr(settings, k, d)
        tau = get("tau_sq_m2") if get("tau_sq_m2") is not None else cls.tau
        tau_c = get("tau_c_sq_m2")
        beta = get("beta") if get("beta") is not None else cls.beta
        oai = get("occlusion_aware") if get("occlusion_aware") is not None else cls.occlusion_aware
        return cls(float(tau), float(beta), 2.0 * tau if tau_c is None else float(tau_c), bool(oai))


def values_torch(points: Tensor, centers, half_sizes, rotations, sp: ScoreParams) -> Tensor:
    """f_OAI(y, {h}) per hypothesis (H, N), or the plain soft inlier f_I(d^2) without OAI."""
    from cuboidcli.geometry import kernels as K

    if sp.occlusion_aware:
        return K.oai_per_cuboid(points, centers, half_sizes, rotations, sp.tau, sp.beta, sp.tau_c)
    local = K.to_local(points, centers, rotations)
    return K.inlier_fn(K.cuboid_sq_distance(local, half_sizes), sp.tau, sp.beta)


def gains_torch(
    points: Tensor, centers, half_sizes, rotations, state: Tensor, sp: ScoreParams, chunk: int = 64
) -> Tensor:
    """Reference gains (H,): sum over points of combine(value, state) - state."""
    import torch

    from cuboidcli.geometry import kernels as K

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
    cells=None,
) -> np.ndarray:
    """Gains (H,) float64 with the fused numba loop, numpy arrays in; ``prune_below`` and ``cells`` as in
    :func:`~cuboidcli.geometry.fused.score_gains`."""
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
        cells,
    )

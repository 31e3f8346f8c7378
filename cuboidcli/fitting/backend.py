"""The kernels a fit scores and refines with, chosen once per fit: :class:`NumbaBackend` (the fused numba
loops, CPU only) or :class:`TorchBackend` (the torch reference kernels, any device).

A backend computes the per-point values f_OAI(y, {h}) of cuboids, the inlier-count gains of hypotheses
over the current state, the selection of the best hypothesis of a batch (:meth:`ScoringBackend.select_best`,
exact or the approximate ``prescore_points`` path, the same algorithm on every backend) and the
refinement of a winner (Adam on the mean squared occlusion-aware distance of its inliers,
:mod:`cuboidcli.fitting.refine`). :func:`backend_for` picks one from a name ("auto", "numba", "torch",
:data:`~cuboidcli.geometry.backends.BACKENDS`) and the points' device; the estimator
(:func:`cuboidcli.fitting.pipeline.fit_points`) does so once and hands it to every step.

Both backends compute in float64 and agree to about 1e-12 per value; the same seed draws the same random
numbers on both, so they select the same cuboids up to rounding.
"""

from __future__ import annotations

from abc import ABC, abstractmethod

import numpy as np
import torch
from torch import Tensor

from cuboidcli.fitting.scoring import ScoreParams, gains_cpu, gains_torch, values_torch
from cuboidcli.geometry.backends import resolve_backend

#: Exact selection: candidates nominated on a random eighth of the points whose best exact gain becomes
#: the pruning threshold (backends that prune).
NOMINATED = 16
#: Margin (in inlier counts) below the nominated threshold, for rounding in the pruned pass.
PRUNE_MARGIN = 1e-6


class ScoringBackend(ABC):
    """Values, gains, selection and winner refinement on one kind of kernels.

    Tensors in: points (N, 3), centers (H, 3), half_sizes (H, 3), rotations (H, 3, 3), state (N,), all on
    the points' device, any float dtype."""

    name: str
    """"numba" or "torch"."""
    prunes: bool = False
    """Whether :meth:`gains` abandons hypotheses below ``prune_below`` (then exact selection nominates a
    threshold first)."""

    @abstractmethod
    def values(self, points: Tensor, centers, half_sizes, rotations, sp: ScoreParams) -> Tensor:
        """f_OAI(y, {h}) of each cuboid on its own (without OAI the plain f_I): (H, N) float64 on the
        points' device."""

    @abstractmethod
    def gains(
        self, points: Tensor, centers, half_sizes, rotations, state, sp: ScoreParams, prune_below=-np.inf
    ) -> np.ndarray:
        """Inlier-count gain of each hypothesis over ``state``: (H,) float64. A backend that prunes reports
        -inf for hypotheses whose gain provably stays below ``prune_below``; the others ignore it."""

    @abstractmethod
    def refine(
        self, points: Tensor, center: Tensor, half: Tensor, rotation: Tensor, a_min: float, a_max: float
    ) -> tuple[Tensor, Tensor, Tensor]:
        """Adam on the mean squared occlusion-aware distance of ``points`` (M, 3) to the cuboid (center (3,),
        half (3,), rotation (3, 3)), half-sizes kept in [a_min, a_max]: the best iterate as
        (center, half, rotation) tensors on the points' device."""

    def select_best(
        self,
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
        """Index and exact gain of the best hypothesis, plus the gains (H,) float64 on the CPU, -inf where
        not computed.

        ``prescore_points == 0`` (default) is exact: every hypothesis is scored on all points and the
        selected one is the true argmax. A backend that prunes first scores all hypotheses on a random
        eighth of the points, takes the best exact gain of the ``NOMINATED`` best of them as a threshold,
        and abandons hypotheses that provably stay below it. ``prescore_points > 0`` is the approximate
        fast path: all hypotheses are scored on that many random points and only the best
        ``rescore_top`` are scored on all points.

        The random subset is drawn from ``generator`` (a CPU generator) on every backend and in both modes,
        also where it is not used, so a seed draws the same random numbers whichever backend scores.
        """
        n = points.shape[0]
        n_sub = prescore_points if prescore_points > 0 else max(n // 8, 1)
        if n_sub >= n:
            g = self.gains(points, centers, half_sizes, rotations, state, sp)
        else:
            sub = torch.randperm(n, generator=generator)[:n_sub].to(points.device)
            if prescore_points > 0 or self.prunes:
                g_sub = self.gains(points[sub], centers, half_sizes, rotations, state[sub], sp)
                k = rescore_top if prescore_points > 0 else NOMINATED
                top = torch.from_numpy(np.argsort(-g_sub, kind="stable")[:k]).to(centers.device)
                g_top = self.gains(points, centers[top], half_sizes[top], rotations[top], state, sp)
            if prescore_points > 0:
                g = np.full(centers.shape[0], -np.inf)
                g[top.cpu().numpy()] = g_top
            elif self.prunes:
                threshold = float(g_top.max()) - PRUNE_MARGIN
                g = self.gains(points, centers, half_sizes, rotations, state, sp, prune_below=threshold)
            else:
                g = self.gains(points, centers, half_sizes, rotations, state, sp)
        best = int(np.argmax(g))
        return best, float(g[best]), torch.from_numpy(g)


class NumbaBackend(ScoringBackend):
    """The fused numba loops of :mod:`cuboidcli.geometry.fused` and :mod:`cuboidcli.solvers.adam_fused`:
    no (H, N, 6) tensors, provable pruning of hypotheses that cannot win. CPU tensors only."""

    name = "numba"
    prunes = True

    def values(self, points, centers, half_sizes, rotations, sp: ScoreParams) -> Tensor:
        from cuboidcli.geometry.fused import cuboid_values

        v = cuboid_values(
            *(_numpy64(x) for x in (points, centers, half_sizes, rotations)),
            sp.tau,
            sp.beta,
            sp.tau_c,
            sp.occlusion_aware,
        )
        return torch.from_numpy(v)

    def gains(self, points, centers, half_sizes, rotations, state, sp: ScoreParams, prune_below=-np.inf):
        arrays = (_numpy64(x) for x in (points, centers, half_sizes, rotations, state))
        return gains_cpu(*arrays, sp, prune_below=prune_below)

    def refine(self, points, center, half, rotation, a_min: float, a_max: float):
        from cuboidcli.fitting.refine import refine_cuboid_fused

        out = refine_cuboid_fused(*(x.numpy() for x in (points, center, half, rotation)), a_min, a_max)
        return tuple(torch.from_numpy(np.asarray(x)) for x in out)

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) every kernel this backend runs, on tiny inputs."""
        p = torch.tensor([[0.0, 0.0, 2.0], [0.1, 0.0, 2.0]], dtype=torch.float64)
        c = torch.tensor([[0.0, 0.0, 2.5]], dtype=torch.float64)
        a = torch.full((1, 3), 0.5, dtype=torch.float64)
        R = torch.eye(3, dtype=torch.float64)[None]
        sp = ScoreParams(0.004, 5.0, 0.008)
        self.gains(p, c, a, R, torch.zeros(2, dtype=torch.float64), sp)
        self.values(p, c, a, R, sp)
        self.refine(p[[0] * 6], c[0], a[0], R[0], 1e-3, 2.0)


class TorchBackend(ScoringBackend):
    """The torch reference kernels of :mod:`cuboidcli.geometry.kernels` in float64, on any device;
    hypotheses are scored ``chunk`` at a time. No pruning: exact selection scores every hypothesis."""

    name = "torch"
    prunes = False

    def __init__(self, chunk: int = 64):
        self.chunk = chunk

    def values(self, points, centers, half_sizes, rotations, sp: ScoreParams) -> Tensor:
        return values_torch(*(x.double() for x in (points, centers, half_sizes, rotations)), sp)

    def gains(self, points, centers, half_sizes, rotations, state, sp: ScoreParams, prune_below=-np.inf):
        tensors = (x.double() for x in (points, centers, half_sizes, rotations, state))
        return gains_torch(*tensors, sp, chunk=self.chunk).cpu().numpy()

    def refine(self, points, center, half, rotation, a_min: float, a_max: float):
        from cuboidcli.fitting.refine import refine_cuboid

        return refine_cuboid(points, center, half, rotation, a_min, a_max)


def backend_for(name: str, device: torch.device | str) -> ScoringBackend:
    """The backend ``name`` ("auto" = numba on the CPU, torch elsewhere; "numba"; "torch") for points on
    ``device``. Raises ValueError for "numba" on a device other than the CPU, or an unknown name."""
    return NumbaBackend() if resolve_backend(name, device) == "numba" else TorchBackend()


def _numpy64(x: Tensor) -> np.ndarray:
    return x.double().numpy()

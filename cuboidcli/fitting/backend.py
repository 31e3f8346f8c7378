"""The kernels a fit scores and refines with, chosen once per fit: :class:`NumbaBackend` (the fused numba
loops, CPU only) or :class:`TorchBackend` (the torch reference kernels, any device).

A backend computes the per-point values f_OAI(y, {h}) of cuboids, the inlier-count gains of hypotheses
over the current state, the selection of the best hypothesis of a batch (:meth:`ScoringBackend.select_best`,
exact or the approximate ``prescore_points`` path, the same algorithm on every backend) and the
refinement of a winner. :func:`backend_for` picks one from a name ("auto", "numba", "torch",
:data:`~cuboidcli.geometry.backends.BACKENDS`) and the points' device; the estimator
(:func:`cuboidcli.fitting.pipeline.fit_points`) does so once and hands it to every step.

Both backends compute in float64 and agree to about 1e-12 per value; the same seed draws the same random
numbers on both, so they select the same hypotheses up to rounding. Rounding can still decide a near-tie
while a winner is refined or grown (two boxes whose gains differ in the first decimal), and from there
the two fits part: same quality, other cuboids.

**Values and gains**: the torch reference kernels and the fused numba loop of
:mod:`cuboidcli.fitting.scoring` (:class:`~cuboidcli.fitting.scoring.ScoreParams`: the inlier function).

**Refining the selected cuboid** on all the points it explains: :meth:`ScoringBackend.refine` runs
:mod:`cuboidcli.fitting.refine`'s Adam (numba or torch).
"""

from __future__ import annotations

import operator
from abc import ABC, abstractmethod
from typing import TYPE_CHECKING

import numpy as np

from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.refine import refine_cuboid, refine_cuboid_fused
from cuboidcli.fitting.scoring import ScoreParams, gains_torch, values_torch
from cuboidcli.geometry.arrays import as_kind, is_tensor, numpy64, on_cpu_as, randperm
from cuboidcli.geometry.backends import resolve_backend

if TYPE_CHECKING:
    import torch
    from torch import Tensor

#: Exact selection: candidates nominated on a random eighth of the points whose best exact gain becomes
#: the pruning threshold (backends that prune).
NOMINATED = 16
#: Margin (in inlier counts) below the nominated threshold, for rounding in the pruned pass.
PRUNE_MARGIN = 1e-6
#: Point-hypothesis pairs per chunk of the torch kernels on a GPU (a few GB of float64 temporaries).
GPU_CHUNK_PAIRS = 2**23
#: The hybrid backend scores this many boxes or fewer on the CPU.
HYBRID_FEW = 64
#: Nomination on a grid: every 2nd row and 4th column (an eighth of the points), hypotheses in blocks.
NOMINATION_GRID = (2, 4)
NOMINATION_BLOCK = 256


class ScoringBackend(ABC):
    """Values, gains, selection and winner refinement on one kind of kernels.

    Arrays in: points (N, 3), centers (H, 3), half_sizes (H, 3), rotations (H, 3, 3), state (N,), all on
    the points' device, any float dtype; tensors, or numpy arrays for a backend that takes them (the
    numba one). What it gives back is of the points' kind."""

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
        self,
        points: Tensor,
        centers,
        half_sizes,
        rotations,
        state,
        sp: ScoreParams,
        prune_below=-np.inf,
        cells=None,
    ) -> np.ndarray:
        """Inlier-count gain of each hypothesis over ``state``: (H,) float64. A backend that prunes reports
        -inf for hypotheses whose gain provably stays below ``prune_below``; the others ignore it.
        ``cells``: the points' :class:`~cuboidcli.geometry.fused.ImageCells` (all points of a fitting
        grid, in its order), which lets a backend skip cells a hypothesis cannot reach; None = unknown."""

    @abstractmethod
    def refine(
        self,
        points: Tensor,
        center: Tensor,
        half: Tensor,
        rotation: Tensor,
        a_min: float,
        a_max: float,
        iters: int = FitConfig.refine_iters,
        lr: float = FitConfig.refine_lr,
    ) -> tuple[Tensor, Tensor, Tensor]:
        """``iters`` steps of Adam (learning rate ``lr``) on the mean squared occlusion-aware distance of
        ``points`` (M, 3) to the cuboid (center (3,), half (3,), rotation (3, 3)), half-sizes kept in
        [a_min, a_max]: the best iterate as (center, half, rotation) tensors on the points' device."""

    def select_best(
        self,
        points: Tensor,
        centers: Tensor,
        half_sizes: Tensor,
        rotations: Tensor,
        state: Tensor,
        sp: ScoreParams,
        generator,
        prescore_points: int = 0,
        rescore_top: int = 64,
    ) -> tuple[int, float, Tensor]:
        """Index and exact gain of the best hypothesis, plus the gains (H,) float64 on the CPU (of the
        points' kind), -inf where not computed.

        ``prescore_points == 0`` (default) is exact: every hypothesis is scored on all points and the
        selected one is the true argmax. A backend that prunes first scores all hypotheses on a random
        eighth of the points, takes the best exact gain of the ``NOMINATED`` best of them as a threshold,
        and abandons hypotheses that provably stay below it. ``prescore_points > 0`` is the approximate
        fast path: all hypotheses are scored on that many random points and only the best
        ``rescore_top`` are scored on all points.

        The random subset is drawn from ``generator`` (the fit's) on every backend and in both modes,
        also where it is not used, so a seed draws the same random numbers whichever backend scores.
        Points bound to their cells (:meth:`bind_cells`) are nominated on a regular eighth of their grid
        instead (:meth:`_nominate`); the random subset is still drawn.
        """
        cells = self.cells_of(points)
        n = points.shape[0]
        n_sub = prescore_points if prescore_points > 0 else max(n // 8, 1)
        if n_sub >= n:
            g = self.gains(points, centers, half_sizes, rotations, state, sp, cells=cells)
        else:
            sub = as_kind(randperm(n, generator)[:n_sub], points)
            if prescore_points > 0 or self.prunes:
                k = rescore_top if prescore_points > 0 else NOMINATED
                if prescore_points == 0 and cells is not None:
                    top = self._nominate(points, centers, half_sizes, rotations, state, sp, cells, k)
                else:
                    g_sub = self.gains(points[sub], centers, half_sizes, rotations, state[sub], sp)
                    top = np.argsort(-g_sub, kind="stable")[:k]
                top = as_kind(top, centers)
                g_top = self.gains(
                    points, centers[top], half_sizes[top], rotations[top], state, sp, cells=cells
                )
            if prescore_points > 0:
                g = np.full(centers.shape[0], -np.inf)
                g[as_kind(top, g)] = g_top
            elif self.prunes:
                threshold = float(g_top.max()) - PRUNE_MARGIN
                g = self.gains(
                    points, centers, half_sizes, rotations, state, sp, prune_below=threshold, cells=cells
                )
            else:
                g = self.gains(points, centers, half_sizes, rotations, state, sp, cells=cells)
        best = int(np.argmax(g))
        return best, float(g[best]), on_cpu_as(g, points)

    def bind_cells(self, points: Tensor, cells) -> None:
        """Tell the backend the :class:`~cuboidcli.geometry.fused.ImageCells` of ``points`` (all the points of
        a fit, in the cells' order): scoring exactly these points then visits only the cells each
        hypothesis can reach. A backend that cannot use them ignores them."""
        self._bound = (points, cells)

    def cells_of(self, points: Tensor):
        """The cells bound to ``points`` (this very array), or None."""
        bound = getattr(self, "_bound", None)
        return bound[1] if bound is not None and bound[0] is points else None

    def _nominate(self, points, centers, half_sizes, rotations, state, sp: ScoreParams, cells, k: int):
        """The ``k`` hypotheses with the highest gains on a regular eighth of the grid (every
        ``NOMINATION_GRID``-th row and column), scored ``NOMINATION_BLOCK`` at a time: each block is pruned
        below the k-th best gain of the blocks before it, since a hypothesis under it cannot be among the
        k best. Returns their indices (k,) int64, best first, ties in index order."""
        idx, sub_cells = cells.subgrid(*NOMINATION_GRID)
        p, s = points[idx], state[idx]
        h = centers.shape[0]
        g = np.full(h, -np.inf)
        kth = -np.inf
        for lo in range(0, h, NOMINATION_BLOCK):
            hi = min(lo + NOMINATION_BLOCK, h)
            part = slice(lo, hi)
            g[part] = self.gains(
                p, centers[part], half_sizes[part], rotations[part], s, sp, kth - PRUNE_MARGIN, sub_cells
            )
            if hi >= k:
                kth = float(np.partition(g[:hi], hi - k)[hi - k])
        return np.argsort(-g, kind="stable")[:k]


class NumbaBackend(ScoringBackend):
    """The fused numba loops of :mod:`cuboidcli.geometry.fused` and :mod:`cuboidcli.geometry.adam`:
    no (H, N, 6) tensors, provable pruning of hypotheses that cannot win. Numpy arrays or CPU tensors."""

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
        return as_kind(v, points)

    def gains(
        self, points, centers, half_sizes, rotations, state, sp: ScoreParams, prune_below=-np.inf, cells=None
    ):
        from cuboidcli.geometry.fused import gains_of
        from cuboidcli.geometry.inlier import inlier_params

        boxes = (_numpy64(x) for x in (centers, half_sizes, rotations))
        params = inlier_params(sp.tau, sp.beta, sp.tau_c, sp.occlusion_aware)
        return gains_of(self._arrays(points, state, cells), *boxes, params, prune_below)

    def _arrays(self, points: Tensor, state: Tensor, cells=None):
        """The :class:`~cuboidcli.geometry.fused.ScoringArrays` of (points, state), kept for the last pair
        scored: a step scores its batches and then the winner's moves against the same two arrays. They are
        held, so their identity (and a tensor's version; the fit replaces a numpy state rather than
        changing it) tells a repeat from new ones."""
        from cuboidcli.geometry.fused import scoring_arrays

        cells = self.cells_of(points) if cells is None else cells
        objects = (points, state, cells)
        versions = (getattr(points, "_version", None), getattr(state, "_version", None))
        cached = getattr(self, "_cache", None)
        if cached is not None and cached[1] == versions and all(map(operator.is_, cached[0], objects)):
            return cached[2]
        arrays = scoring_arrays(_numpy64(points), _numpy64(state), cells)
        self._cache = (objects, versions, arrays)
        return arrays

    def refine(
        self, points, center, half, rotation, a_min: float, a_max: float,
        iters: int = FitConfig.refine_iters, lr: float = FitConfig.refine_lr,
    ):  # fmt: skip
        arrays = (numpy64(x) for x in (points, center, half, rotation))
        out = refine_cuboid_fused(*arrays, a_min, a_max, iters, lr)
        return tuple(as_kind(np.asarray(x), points) for x in out)

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) every kernel this backend runs, on tiny inputs."""
        p = np.array([[0.0, 0.0, 2.0], [0.1, 0.0, 2.0]])
        c = np.array([[0.0, 0.0, 2.5]])
        a = np.full((1, 3), 0.5)
        R = np.eye(3)[None]
        sp = ScoreParams(0.004, 5.0, 0.008)
        from cuboidcli.geometry.cells import ImageCells

        self.gains(p, c, a, R, np.zeros(2), sp)
        cells = ImageCells.of_grid(np.array([0, 1]), np.array([0.0, 0.05]), np.array([0.0]))
        self.gains(p, c, a, R, np.zeros(2), sp, cells=cells)
        self.values(p, c, a, R, sp)
        self.refine(p[[0] * 6], c[0], a[0], R[0], 1e-3, 2.0)


class TorchBackend(ScoringBackend):
    """The torch reference kernels of :mod:`cuboidcli.geometry.kernels` in float64, on any device;
    hypotheses are scored ``chunk`` at a time. No pruning: exact selection scores every hypothesis.
    Numpy arrays given to it (labelling points after a fit) become CPU tensors."""

    name = "torch"
    prunes = False

    def __init__(self, chunk: int | None = None):
        self.chunk = chunk
        """Hypotheses per chunk; None = 64 on the CPU, as many as ``GPU_CHUNK_PAIRS`` allow on a GPU."""

    def _chunk(self, points: Tensor) -> int:
        if self.chunk is not None:
            return self.chunk
        if points.device.type == "cpu":
            return 64
        return max(64, GPU_CHUNK_PAIRS // max(points.shape[0], 1))

    def values(self, points, centers, half_sizes, rotations, sp: ScoreParams) -> Tensor:
        return values_torch(*(_tensor64(x) for x in (points, centers, half_sizes, rotations)), sp)

    def gains(
        self, points, centers, half_sizes, rotations, state, sp: ScoreParams, prune_below=-np.inf, cells=None
    ):
        tensors = [_tensor64(x) for x in (points, centers, half_sizes, rotations, state)]
        return gains_torch(*tensors, sp, chunk=self._chunk(tensors[0])).cpu().numpy()

    def refine(
        self, points, center, half, rotation, a_min: float, a_max: float,
        iters: int = FitConfig.refine_iters, lr: float = FitConfig.refine_lr,
    ):  # fmt: skip
        return refine_cuboid(points, center, half, rotation, a_min, a_max, iters, lr)


class HybridBackend(TorchBackend):
    """For points on a GPU ("auto" there): whole batches of hypotheses are scored by the torch kernels on
    the GPU, in chunks as large as ``GPU_CHUNK_PAIRS`` allow; a few boxes at a time (a winner's values, its
    face moves while it grows, the nominated candidates) and refinement run in the numba loops on a CPU
    copy of the points, where a GPU would mostly wait for its kernel launches. Same values as either."""

    name = "hybrid"

    def __init__(self) -> None:
        super().__init__()
        self._cpu = NumbaBackend()
        self._hosted: list = []  # (tensor on the GPU, its version, its CPU copy), the last two

    def _host(self, x: Tensor) -> Tensor:
        """A CPU float64 copy of ``x``, kept for the points and the state a step scores again and again."""
        for t, version, copy in self._hosted:
            if t is x and version == x._version:
                return copy
        copy = x.detach().double().cpu()
        self._hosted = [(x, x._version, copy)] + self._hosted[:1]
        return copy

    def bind_cells(self, points: Tensor, cells) -> None:
        super().bind_cells(points, cells)
        self._cpu.bind_cells(self._host(points), cells)

    def values(self, points, centers, half_sizes, rotations, sp: ScoreParams) -> Tensor:
        if centers.shape[0] > HYBRID_FEW:
            return super().values(points, centers, half_sizes, rotations, sp)
        boxes = (x.detach().double().cpu() for x in (centers, half_sizes, rotations))
        return self._cpu.values(self._host(points), *boxes, sp).to(points.device)

    def gains(
        self, points, centers, half_sizes, rotations, state, sp: ScoreParams, prune_below=-np.inf, cells=None
    ):
        if centers.shape[0] > HYBRID_FEW:
            return super().gains(points, centers, half_sizes, rotations, state, sp)
        boxes = (x.detach().double().cpu() for x in (centers, half_sizes, rotations))
        return self._cpu.gains(self._host(points), *boxes, self._host(state), sp)

    def refine(
        self, points, center, half, rotation, a_min: float, a_max: float,
        iters: int = FitConfig.refine_iters, lr: float = FitConfig.refine_lr,
    ):  # fmt: skip
        boxes = (x.detach().double().cpu() for x in (points, center, half, rotation))
        out = self._cpu.refine(*boxes, a_min, a_max, iters, lr)
        return tuple(x.to(points.device) for x in out)


def backend_for(name: str, device: torch.device | str) -> ScoringBackend:
    """The backend ``name`` ("auto" = numba on the CPU, hybrid elsewhere; "numba"; "torch") for points on
    ``device``. Raises ValueError for "numba" on a device other than the CPU, or an unknown name."""
    kind = resolve_backend(name, device)
    return {"numba": NumbaBackend, "hybrid": HybridBackend}.get(kind, TorchBackend)()


def _numpy64(x) -> np.ndarray:
    return numpy64(x)


def _tensor64(x) -> Tensor:
    """``x`` as a float64 tensor (a numpy array on the CPU)."""
    if is_tensor(x):
        return x.double()
    import torch

    return torch.from_numpy(np.asarray(x, dtype=np.float64))

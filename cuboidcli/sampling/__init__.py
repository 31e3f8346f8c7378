"""Sampling minimal sets (paper Sec. 3.2.1): per-point sampling weights from which minimal sets are drawn.

A sampler returns Q sampling distributions over the fitting points and a selection distribution q over
them. A hypothesis first picks a distribution by q, then draws its C points from it with replacement.
Uniform sampling has Q = 1; the learned sampler (Q = 4) is in :mod:`cuboidcli.sampling.learned`, minimal
sets localised in a 3D ball in :mod:`cuboidcli.sampling.proposals`. :func:`cuboidcli.factories.make_sampler`
builds a sampler by name. Fitting imports this package; it imports neither fitting, the solvers nor the
weights registry.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

import numpy as np

from cuboidcli.geometry.arrays import (
    categorical,
    clamp,
    float64,
    indices_of_generator,
    is_tensor,
    is_torch_generator,
    like,
    namespace,
    numpy64,
)
from cuboidcli.sampling.space import SpaceCells

if TYPE_CHECKING:
    from torch import Tensor


@dataclass
class SamplingContext:
    """What a sampler may look at in one step, as numpy arrays or as tensors (the fit's kind).

    points (N, 3) valid fitting points, metres; grid_index (N,) flat index of each point in the fitting grid
    of shape grid_shape (Hs, Ws); depth_grid (Hs, Ws) metres with 0 where invalid; state (N,) = f_OAI of the
    cuboids selected so far (negative where occluded, 0 before the first).
    """

    points: Tensor
    grid_index: Tensor
    grid_shape: tuple[int, int]
    depth_grid: Tensor
    state: Tensor
    step: int
    focal_cells: tuple[float, float] | None = None
    """Focal lengths in fitting-grid cells (fx / grid_step, fy / grid_step); None = estimated from the
    points when a localised proposal needs them."""
    space: SpaceCells | None = None
    """For unorganised points (a room, no image grid): their voxel cells, where localised sets find the
    ball around their first point (:mod:`cuboidcli.sampling.space`)."""


class Sampler(Protocol):
    name: str
    takes_numpy: bool
    """Whether :meth:`distributions` takes a context of numpy arrays (and gives numpy arrays back); a
    sampler without it gets tensors (a network's)."""

    def distributions(self, ctx: SamplingContext) -> tuple[Tensor, Tensor]:
        """Returns (p (Q, N) rows summing to 1, q (Q,) summing to 1)."""
        ...

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the kernels drawing this sampler's minimal sets runs, once per
        process; the estimator calls it before it times anything."""
        ...


class SamplerBase:
    """What the samplers here share: minimal sets are drawn from their distributions by
    :func:`draw_hypotheses`, whose localised sets run numba kernels."""

    name: str
    takes_numpy = True
    """The samplers here compute their weights on numpy arrays or tensors alike."""

    def warm_up(self) -> None:
        """Compile the kernels of localised minimal sets
        (:func:`~cuboidcli.sampling.proposals.warm_up_minimal_sets`), once per process."""
        from cuboidcli.sampling.proposals import warm_up_minimal_sets

        warm_up_minimal_sets()


class UniformSampler(SamplerBase):
    """Every valid point equally likely: Sequential RANSAC's uniform sampling."""

    name = "uniform"

    def distributions(self, ctx: SamplingContext) -> tuple[Tensor, Tensor]:
        n = ctx.points.shape[0]
        ref = float64(ctx.points[:1, 0])
        return like(np.full((1, n), 1.0 / n), ref), like(np.ones(1), ref)


class SequentialSampler(SamplerBase):
    """Weights 1 - max(f_OAI(y, M), 0): points already explained are sampled less (the paper's
    Sequential RANSAC baseline with soft inlier removal)."""

    name = "sequential"

    def distributions(self, ctx: SamplingContext) -> tuple[Tensor, Tensor]:
        w = clamp(1.0 - clamp(float64(ctx.state), 0.0), 0.0)
        total = w.sum()
        if total <= 1e-12:
            w = namespace(w).ones_like(w)
            total = w.sum()
        return (w / total)[None], like(np.ones(1), w)


class LocalSampler(SequentialSampler):
    """Sequential-RANSAC weights for the first point; every minimal set localised in a 3D ball around it
    (``local_fraction`` 1, whatever the configuration says; see :mod:`cuboidcli.sampling.proposals`)."""

    name = "local"
    local_fraction = 1.0


def build_uniform(inputs) -> UniformSampler:
    """The ``uniform`` sampler of the parts registry; it reads nothing of its ``BuildInputs``."""
    return UniformSampler()


def build_sequential(inputs) -> SequentialSampler:
    """The ``sequential`` sampler of the parts registry; it reads nothing of its ``BuildInputs``."""
    return SequentialSampler()


def build_local(inputs) -> LocalSampler:
    """The ``local`` sampler of the parts registry; it reads nothing of its ``BuildInputs``."""
    return LocalSampler()


def draw_sets_and_maps(p, q, hypotheses: int, min_set: int, generator) -> tuple:
    """Minimal sets: map j(h) ~ q per hypothesis, then C points ~ p_j with replacement.

    p (Q, N), q (Q,) -> (maps (H,) int64, indices (H, C) int64), tensors for a torch generator, else numpy
    arrays. The chosen maps are what the sampler's policy gradient needs. Draws happen on the CPU
    generator so that results do not depend on the device.
    """
    if is_torch_generator(generator):  # torch draws from the tensors as they are
        p, q = (x.detach().double().cpu() if is_tensor(x) else _tensor(x) for x in (p, q))
    else:
        p, q = numpy64(p), numpy64(q)
    if p.shape[0] == 1:
        maps = np.zeros(hypotheses, dtype=np.int64)
    else:
        maps = categorical(q, hypotheses, generator)
    idx = np.empty((hypotheses, min_set), dtype=np.int64)
    for j in range(p.shape[0]):
        sel = np.flatnonzero(maps == j)
        if sel.size:
            idx[sel] = categorical(p[j], sel.size * min_set, generator).reshape(-1, min_set)
    return indices_of_generator(maps, generator), indices_of_generator(idx, generator)


def _tensor(x: np.ndarray):
    import torch

    return torch.from_numpy(np.asarray(x, dtype=np.float64))


def draw_minimal_sets(p, q, hypotheses: int, min_set: int, generator):
    """Indices (H, C) of minimal sets drawn as :func:`draw_sets_and_maps`."""
    return draw_sets_and_maps(p, q, hypotheses, min_set, generator)[1]


def local_fraction_of(sampler: Sampler, configured: float) -> float:
    """The share of localised minimal sets a sampler uses: its own ``local_fraction`` if it fixes one (the
    local sampler: 1), else the configured one."""
    return float(getattr(sampler, "local_fraction", configured))


def draw_hypotheses(
    sampler: Sampler,
    ctx: SamplingContext,
    hypotheses: int,
    min_set: int,
    generator,
    local_fraction: float = 0.0,
    radii_m: tuple[float, ...] | None = None,
    dists: tuple[Tensor, Tensor] | None = None,
) -> tuple:
    """One batch of minimal sets: the first ``round(local_fraction * hypotheses)`` localised (first point
    from the sampler's maps, the others from a 3D ball around it), the rest global (all C points from the
    maps, the paper's sets). Returns (maps (H,), indices (H, C), local (H,) bool), all on the CPU:
    tensors for a torch ``generator``, numpy arrays for numpy's."""
    from cuboidcli.sampling.proposals import DEFAULT_RADII_M, ball_minimal_sets, neighbour_weights
    from cuboidcli.sampling.space import space_minimal_sets

    frac = local_fraction_of(sampler, local_fraction)
    n_local = min(max(round(frac * hypotheses), 0), hypotheses)
    p, q = dists if dists is not None else sampler.distributions(ctx)
    maps = np.empty(hypotheses, dtype=np.int64)
    idx = np.empty((hypotheses, min_set), dtype=np.int64)
    if n_local:
        maps[:n_local], seeds = draw_sets_and_maps(p, q, n_local, 1, generator)
        weights = neighbour_weights(ctx.state)
        radii = radii_m or DEFAULT_RADII_M
        if ctx.space is not None:
            idx[:n_local] = space_minimal_sets(ctx.space, seeds[:, 0], min_set, generator, radii, weights)
        else:
            idx[:n_local] = ball_minimal_sets(
                ctx.points, ctx.grid_index, ctx.grid_shape, seeds[:, 0], min_set, generator, radii, weights,
                ctx.focal_cells,
            )  # fmt: skip
    if n_local < hypotheses:
        maps[n_local:], idx[n_local:] = draw_sets_and_maps(p, q, hypotheses - n_local, min_set, generator)
    local = np.zeros(hypotheses, dtype=bool)
    local[:n_local] = True
    return tuple(indices_of_generator(x, generator) for x in (maps, idx, local))

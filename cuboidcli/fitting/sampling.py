"""Samplers: per-point sampling weights from which minimal sets are drawn (paper Sec. 3.2.1).

A sampler returns Q sampling distributions over the fitting points and a selection distribution q over
them. A hypothesis first picks a distribution by q, then draws its C points from it with replacement.
Uniform sampling has Q = 1; the learned sampler (Q = 4) lives in :mod:`cuboidcli.learn`.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import torch
from torch import Tensor


@dataclass
class SamplingContext:
    """What a sampler may look at in one step.

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


class Sampler(Protocol):
    name: str

    def distributions(self, ctx: SamplingContext) -> tuple[Tensor, Tensor]:
        """Returns (p (Q, N) rows summing to 1, q (Q,) summing to 1)."""
        ...


class UniformSampler:
    """Every valid point equally likely: Sequential RANSAC's uniform sampling."""

    name = "uniform"

    def distributions(self, ctx: SamplingContext) -> tuple[Tensor, Tensor]:
        n = ctx.points.shape[0]
        p = torch.full((1, n), 1.0 / n, dtype=torch.float64, device=ctx.points.device)
        return p, torch.ones(1, dtype=torch.float64, device=ctx.points.device)


class SequentialSampler:
    """Weights 1 - max(f_OAI(y, M), 0): points already explained are sampled less (the paper's
    Sequential RANSAC baseline with soft inlier removal)."""

    name = "sequential"

    def distributions(self, ctx: SamplingContext) -> tuple[Tensor, Tensor]:
        w = (1.0 - ctx.state.double().clamp_min(0.0)).clamp_min(0.0)
        total = w.sum()
        if total <= 1e-12:
            w = torch.ones_like(w)
            total = w.sum()
        return (w / total)[None], torch.ones(1, dtype=torch.float64, device=w.device)


class LocalSampler(SequentialSampler):
    """Sequential-RANSAC weights for the first point of a minimal set, the other C - 1 points drawn from a
    window of the fitting grid around it (NAPSAC-style localised sampling; not in the paper).

    A structure covering a fraction f of the points yields an all-inlier set with probability ~f^6 under
    global sampling (1e-4 for f = 0.2), so small furniture is rarely found without a learned sampler; drawn
    from a neighbourhood, the six points usually share a structure. The window half-width is drawn per
    hypothesis from [2, 12] grid cells (16-96 pixels at the default grid step) to cover several scales.
    """

    name = "local"
    min_half_width = 2
    max_half_width = 12

    def draw(self, ctx: SamplingContext, hypotheses: int, min_set: int, generator: torch.Generator) -> Tensor:
        p, q = self.distributions(ctx)
        seeds = draw_minimal_sets(p, q, hypotheses, 1, generator)[:, 0]
        hs, ws = ctx.grid_shape
        gi = ctx.grid_index.cpu()
        cell_to_point = torch.full((hs * ws,), -1, dtype=torch.long)
        cell_to_point[gi] = torch.arange(gi.numel())
        rows, cols = gi[seeds] // ws, gi[seeds] % ws
        half = torch.randint(
            self.min_half_width, self.max_half_width + 1, (hypotheses, 1), generator=generator
        )
        idx = seeds[:, None].repeat(1, min_set)
        todo = torch.ones(hypotheses, min_set - 1, dtype=torch.bool)
        for _ in range(6):  # redraw cells without valid depth a few times, then keep the seed point
            u = torch.rand(hypotheses, min_set - 1, 2, generator=generator)
            r = (rows[:, None] + ((2 * u[..., 0] - 1) * (half + 0.5)).round().long()).clamp(0, hs - 1)
            c = (cols[:, None] + ((2 * u[..., 1] - 1) * (half + 0.5)).round().long()).clamp(0, ws - 1)
            cand = cell_to_point[r * ws + c]
            take = todo & (cand >= 0)
            idx[:, 1:] = torch.where(take, cand, idx[:, 1:])
            todo &= ~take
            if not todo.any():
                break
        return idx


def draw_sets_and_maps(
    p: Tensor, q: Tensor, hypotheses: int, min_set: int, generator: torch.Generator
) -> tuple[Tensor, Tensor]:
    """Minimal sets: map j(h) ~ q per hypothesis, then C points ~ p_j with replacement.

    p (Q, N), q (Q,) -> (maps (H,) long, indices (H, C) long). The chosen maps are what the sampler's
    policy gradient needs. Draws happen on the CPU generator so that results do not depend on the device.
    """
    p = p.detach().double().cpu()
    q = q.detach().double().cpu()
    if p.shape[0] == 1:
        maps = torch.zeros(hypotheses, dtype=torch.long)
    else:
        maps = torch.multinomial(q, hypotheses, replacement=True, generator=generator)
    idx = torch.empty(hypotheses, min_set, dtype=torch.long)
    for j in range(p.shape[0]):
        sel = (maps == j).nonzero().squeeze(1)
        if sel.numel():
            draws = torch.multinomial(p[j], sel.numel() * min_set, replacement=True, generator=generator)
            idx[sel] = draws.view(-1, min_set)
    return maps, idx


def draw_minimal_sets(
    p: Tensor, q: Tensor, hypotheses: int, min_set: int, generator: torch.Generator
) -> Tensor:
    """Indices (H, C) of minimal sets drawn as :func:`draw_sets_and_maps`."""
    return draw_sets_and_maps(p, q, hypotheses, min_set, generator)[1]


def make_sampler(name: str, weights_dir=None, device: str = "cpu") -> Sampler:
    if name == "uniform":
        return UniformSampler()
    if name == "sequential":
        return SequentialSampler()
    if name == "local":
        return LocalSampler()
    if name == "learned":
        from cuboidcli.bundles import weights_for
        from cuboidcli.learn.sampler_net import LearnedSampler

        return LearnedSampler.load(weights_for("sampler", weights_dir), device=device)
    raise ValueError(f"unknown sampler {name!r}; choose uniform, sequential, local or learned")

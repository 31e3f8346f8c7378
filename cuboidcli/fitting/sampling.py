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


def draw_minimal_sets(
    p: Tensor, q: Tensor, hypotheses: int, min_set: int, generator: torch.Generator
) -> Tensor:
    """Indices (H, C) of minimal sets: map j ~ q per hypothesis, then C points ~ p_j with replacement.

    Draws happen on the CPU generator so that results do not depend on the device.
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
    return idx


def make_sampler(name: str, weights_dir=None, device: str = "cpu") -> Sampler:
    if name == "uniform":
        return UniformSampler()
    if name == "sequential":
        return SequentialSampler()
    if name == "learned":
        from cuboidcli.learn.sampler_net import LearnedSampler

        return LearnedSampler.load(weights_dir, device=device)
    raise ValueError(f"unknown sampler {name!r}; choose uniform, sequential or learned")

"""The learned sampler: the sampling-weight network (:mod:`cuboidcli.nets.sampler`) as a Sampler.

The network sees the fitting grid of a :class:`~cuboidcli.sampling.SamplingContext` (depth and the state
of the cuboids selected so far) and returns Q sampling-weight maps and selection weights q. The context is
only read here, so it is imported for type checking alone: this module never imports the package. Which
weights file to load is decided by :func:`cuboidcli.factories.load_learned_sampler`.
"""

from __future__ import annotations

import os
from pathlib import Path
from typing import TYPE_CHECKING

import torch
from torch import Tensor

from cuboidcli.nets.sampler import SamplerNet, net_from_checkpoint

if TYPE_CHECKING:
    from cuboidcli.sampling import SamplingContext


def grid_inputs(ctx: SamplingContext) -> tuple[Tensor, Tensor, Tensor]:
    """A sampling context as network input (1, Hs, Ws) each: depth m, state, valid mask.

    Validity comes from ``grid_index`` (the fitting points) so that the maps cover exactly those points.
    """
    hs, ws = ctx.grid_shape
    device = ctx.depth_grid.device
    idx = ctx.grid_index.to(device)
    valid = torch.zeros(hs * ws, dtype=torch.bool, device=device)
    valid[idx] = True
    state = torch.zeros(hs * ws, dtype=torch.float32, device=device)
    state[idx] = ctx.state.to(device, torch.float32)
    depth = ctx.depth_grid.to(torch.float32).reshape(hs * ws)
    return depth.view(1, hs, ws), state.view(1, hs, ws), valid.view(1, hs, ws)


class LearnedSampler:
    """Sampler (``name = "learned"``) backed by :class:`SamplerNet`: Q = config.maps distributions.

    ``distributions(ctx)`` returns p (Q, N) float64, each row summing to 1 over the N fitting points, and
    q (Q,) float64. The net runs in eval mode without gradients.
    """

    name = "learned"

    def __init__(self, net: SamplerNet, device: str | torch.device = "cpu") -> None:
        self.device = torch.device(device)
        self.net = net.to(self.device).eval()

    @classmethod
    def load(cls, path: str | os.PathLike, device: str = "cpu") -> LearnedSampler:
        """Load a sampler weights file (``sampler_v2.pt``); raises FileNotFoundError when it is missing."""
        path = Path(path)
        if not path.is_file():
            raise FileNotFoundError(
                f"sampler weights {path} not found; train them with 'cuboids train sampler DATA' and pass "
                "their folder with --weights, or use --sampler sequential"
            )
        from cuboidcli.io.checkpoints import load_net

        return cls(load_net(path, "sampler", net_from_checkpoint), device)

    def warm_up(self) -> None:
        """Compile the kernels of localised minimal sets, once per process (the network needs none)."""
        from cuboidcli.sampling.proposals import warm_up_minimal_sets

        warm_up_minimal_sets()

    def distributions(self, ctx: SamplingContext) -> tuple[Tensor, Tensor]:
        depth, state, valid = (t.to(self.device) for t in grid_inputs(ctx))
        with torch.no_grad():
            out = self.net(depth, state, valid)
        idx = ctx.grid_index.to(self.device)
        p = out.p[0].flatten(1)[:, idx].double()  # (Q, N)
        # float32 softmax sums deviate from 1 by ~1e-7; renormalise in float64 for the multinomial draws
        p = p / p.sum(1, keepdim=True)
        q = out.q[0].double()
        return p.to(ctx.points.device), (q / q.sum()).to(ctx.points.device)


def build(inputs) -> LearnedSampler:
    """The sampler of the parts registry (``learned``) from a ``BuildInputs``: the network in
    ``inputs.weights`` (found by the factories) on ``inputs.device``."""
    return LearnedSampler.load(inputs.weights, device=inputs.device)

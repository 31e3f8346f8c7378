"""Sampling minimal sets (paper Sec. 3.2.1): samplers give per-point sampling weights, minimal sets of C
points are drawn from them.

Modules: :mod:`.base` (the :class:`SamplingContext` a sampler sees, the :class:`Sampler` protocol, the
uniform, sequential and local samplers, drawing minimal sets), :mod:`.proposals` (minimal sets localised in
a 3D ball), :mod:`.learned` (the sampling-weight network as a Sampler). :func:`make_sampler` builds a
sampler by name. Fitting imports this package; it imports neither fitting nor the solvers.
"""

from __future__ import annotations

from cuboidcli.sampling.base import (
    LocalSampler,
    Sampler,
    SamplingContext,
    SequentialSampler,
    UniformSampler,
    draw_hypotheses,
    draw_minimal_sets,
    draw_sets_and_maps,
    local_fraction_of,
)

__all__ = [
    "LocalSampler",
    "Sampler",
    "SamplingContext",
    "SequentialSampler",
    "UniformSampler",
    "draw_hypotheses",
    "draw_minimal_sets",
    "draw_sets_and_maps",
    "local_fraction_of",
    "make_sampler",
]


def make_sampler(name: str, weights_dir=None, device: str = "cpu") -> Sampler:
    if name == "uniform":
        return UniformSampler()
    if name == "sequential":
        return SequentialSampler()
    if name == "local":
        return LocalSampler()
    if name == "learned":
        from cuboidcli.sampling.learned import LearnedSampler
        from cuboidcli.weights import weights_for

        return LearnedSampler.load(weights_for("sampler", weights_dir), device=device)
    raise ValueError(f"unknown sampler {name!r}; choose uniform, sequential, local or learned")

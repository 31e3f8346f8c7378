"""The interface every cuboid solver implements, so that the estimator does not care which one runs."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

from torch import Tensor


@dataclass(frozen=True)
class SizeBounds:
    """Half-size bounds [a_min, a_max] in metres (paper appendix: 1e-3 and 2.0 for NYU, 2 and 30 outdoors)."""

    a_min: float = 1e-3
    a_max: float = 2.0


class CuboidSolver(Protocol):
    """Fits one cuboid per minimal set.

    ``minimal_sets`` is (H, C, 3) in camera coordinates (metres). Returns ``(centers (H, 3),
    half_sizes (H, 3), rotations (H, 3, 3))`` with half-sizes inside the solver's bounds, in the dtype and
    on the device of the input. Must be deterministic for a given input.
    """

    name: str
    bounds: SizeBounds

    def __call__(self, minimal_sets: Tensor) -> tuple[Tensor, Tensor, Tensor]: ...

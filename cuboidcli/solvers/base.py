"""The interface every cuboid solver implements, so that the estimator does not care which one runs."""

from __future__ import annotations

from dataclasses import dataclass
from typing import Protocol

import numpy as np
import torch
from torch import Tensor

from cuboidcli.geometry.gravity import upright_rotation


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


def solve_upright(
    solver: CuboidSolver, minimal_sets: Tensor, frame: Tensor, fixed: bool = False
) -> tuple[Tensor, Tensor, Tensor]:
    """Upright boxes for minimal sets (H, C, 3) in camera coordinates: one axis along the up direction,
    the box turning about it only (``fixed``: not at all; the frame's horizontal axes are the room's).

    ``frame`` (3, 3) has the world axes as columns in camera coordinates, its third column up. A solver
    with a ``solve_upright`` method (the numerical one) fits yaw-only boxes in that frame; any other fits a
    free box there, which is then turned upright (:func:`upright_nearest`). Returns camera-frame
    (centers, half_sizes, rotations) like ``solver(minimal_sets)``."""
    g = frame.to(minimal_sets)
    world = minimal_sets @ g
    if hasattr(solver, "solve_upright"):
        c, a, r = solver.solve_upright(world, fixed)
    else:
        c, a, r = solver(world)
        r = upright_nearest(r)
    return c @ g.T, a, g @ r


def upright_nearest(rotations: Tensor) -> Tensor:
    """The upright rotations (H, 3, 3) nearest to ``rotations`` in a frame whose z axis is up
    (:func:`~cuboidcli.geometry.gravity.upright_rotation` for each)."""
    up = np.array([0.0, 0.0, 1.0])
    out = [upright_rotation(r, up) for r in rotations.detach().double().cpu().numpy()]
    return torch.from_numpy(np.stack(out)).to(rotations)

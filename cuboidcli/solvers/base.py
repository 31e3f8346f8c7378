"""The interface every cuboid solver implements, so that the estimator does not care which one runs."""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Protocol

from cuboidcli.geometry.arrays import cast_like

if TYPE_CHECKING:
    from torch import Tensor


@dataclass(frozen=True)
class SizeBounds:
    """Half-size bounds [a_min, a_max] in metres (paper appendix: 1e-3 and 2.0 for NYU, 2 and 30 outdoors)."""

    a_min: float = 1e-3
    a_max: float = 2.0

    @classmethod
    def of(cls, config) -> SizeBounds:
        """The bounds a fit's settings give (``config.a_min``, ``config.a_max``), read by attribute: the
        settings live in a layer above the solvers."""
        return cls(config.a_min, config.a_max)


class CuboidSolver(Protocol):
    """Fits one cuboid per minimal set.

    ``minimal_sets`` is (H, C, 3) in camera coordinates (metres). Returns ``(centers (H, 3),
    half_sizes (H, 3), rotations (H, 3, 3))`` with half-sizes inside the solver's bounds, in the dtype and
    on the device of the input. Must be deterministic for a given input.

    A solver whose ``takes_numpy`` is true takes numpy arrays too (and gives numpy arrays back); the
    others are given tensors.
    """

    name: str
    bounds: SizeBounds
    takes_numpy: bool

    def __call__(self, minimal_sets: Tensor) -> tuple[Tensor, Tensor, Tensor]: ...

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the kernels the solver runs, once; the estimator calls it
        before it times anything. A solver without compiled kernels does nothing."""
        ...


def solve_upright(
    solver: CuboidSolver, minimal_sets: Tensor, frame: Tensor, fixed: bool = False
) -> tuple[Tensor, Tensor, Tensor]:
    """Upright boxes for minimal sets (H, C, 3) in camera coordinates: one axis along the up direction,
    the box turning about it only (``fixed``: not at all; the frame's horizontal axes are the room's).

    ``frame`` (3, 3) has the world axes as columns in camera coordinates, its third column up. A solver
    with a ``solve_upright`` method (the numerical one) fits yaw-only boxes in that frame; any other fits a
    free box there, which is then turned upright (:func:`upright_nearest`). Returns camera-frame
    (centers, half_sizes, rotations) like ``solver(minimal_sets)``; ``frame`` may be a numpy array for
    tensor sets."""
    g = cast_like(frame, minimal_sets)
    world = minimal_sets @ g
    if hasattr(solver, "solve_upright"):
        c, a, r = solver.solve_upright(world, fixed)
    else:
        c, a, r = solver(world)
        r = upright_nearest(r)
    return c @ g.T, a, g @ r


def upright_nearest(rotations: Tensor) -> Tensor:
    """The upright rotations (H, 3, 3) nearest to ``rotations`` in a frame whose z axis is up: for each, the
    column most parallel to z is turned onto +-z by the smallest rotation, which turns the other two with
    it (:func:`~cuboidcli.geometry.gravity.upright_rotation`, batched). Tensors."""
    import torch

    r = rotations.double()
    k = r[:, 2, :].abs().argmax(-1)  # the column most parallel to up
    src = torch.gather(r, 2, k[:, None, None].expand(-1, 3, 1))[..., 0]  # (H, 3)
    dst = torch.zeros_like(src)
    dst[:, 2] = torch.where(src[:, 2] >= 0, 1.0, -1.0)
    v = torch.linalg.cross(src, dst)
    s = v.norm(dim=-1)
    c = (src * dst).sum(-1)  # |src_z| >= 1/sqrt(3): never a half turn
    kx = torch.zeros_like(r)
    n = v / s.clamp_min(1e-300)[:, None]
    kx[:, 0, 1], kx[:, 0, 2], kx[:, 1, 2] = -n[:, 2], n[:, 1], -n[:, 0]
    kx[:, 1, 0], kx[:, 2, 0], kx[:, 2, 1] = n[:, 2], -n[:, 1], n[:, 0]
    eye = torch.eye(3, dtype=r.dtype, device=r.device).expand_as(r)
    turn = eye + s[:, None, None] * kx + (1.0 - c)[:, None, None] * (kx @ kx)
    turn = torch.where((s < 1e-12)[:, None, None], eye, turn)
    return (turn @ r).to(rotations)

"""Numerical cuboid solver (paper Sec. 3.2.2): PCA initialisation, then Adam on F = d^2 (a_x + a_y + a_z).

All hypotheses are optimised at once as one batch. Adam's update is element-wise, so optimising the sum of
the per-hypothesis objectives is the same as running one optimiser per hypothesis; the best iterate is
kept per hypothesis (the research code kept it by the batch mean — see NOTES.md).
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np

from cuboidcli.geometry.arrays import device_of, like, numpy64
from cuboidcli.geometry.backends import resolve_backend
from cuboidcli.geometry.rotations import axis_angle_to_matrix, matrix_to_axis_angle
from cuboidcli.solvers.base import SizeBounds

if TYPE_CHECKING:
    from torch import Tensor

#: Adam steps of a box on the room's axes (no rotation parameter): its objective is then nearly convex in
#: the centre and sizes. On minimal sets drawn while fitting two NYU frames, 30 steps come within 1.2 % of
#: the objective that 100 steps reach (median; 20 steps: 2.8 %), where a yaw-only box needs the full 50
#: (3.8 %; 30 steps: 21 %).
FIXED_AXES_ITERS = 30


def pca_init(points: Tensor, bounds: SizeBounds) -> tuple[Tensor, Tensor, Tensor]:
    """Initial cuboid of each minimal set (H, C, 3): the bounding box in the PCA frame.

    The rotation's columns are the principal directions V (so y_hat = V^T (y - t0), the paper's R0 = V^T);
    the box is centred on the PCA-frame bounding box and that offset is mapped back with V (the research
    code used V^T here, leaving the centre ~10 cm off). Tensors (the CPU path is
    :func:`~cuboidcli.solvers.init_fused.pca_boxes`).
    """
    import torch

    mean = points.mean(1)
    centred = points - mean[:, None]
    # SVD of the small (C x 3) matrices; float64 for stability with nearly-collinear sets.
    _, _, vh = torch.linalg.svd(centred.double(), full_matrices=False)
    v = vh.transpose(-1, -2).to(points.dtype)  # (H, 3, 3), columns = principal axes
    # the signs the CPU path (solvers/init_fused.py) uses: each of the first two axes with its largest
    # component positive, the third their cross product (a proper rotation)
    first = v[..., :2]
    largest = first.abs().argmax(-2, keepdim=True)
    first = first * torch.gather(first, -2, largest).sign()
    v = torch.cat([first, torch.linalg.cross(first[..., 0], first[..., 1])[..., None]], -1)
    local = centred @ v
    lo, hi = local.amin(1), local.amax(1)
    offset = 0.5 * (lo + hi)
    center = mean + (v @ offset[..., None])[..., 0]
    half = (0.5 * (hi - lo)).clamp(bounds.a_min, bounds.a_max)
    return center, half, v


def upright_init(points: Tensor, bounds: SizeBounds, fixed: bool) -> tuple[Tensor, Tensor, Tensor]:
    """Initial upright cuboid of each minimal set (H, C, 3) given in a frame whose z axis is up: the
    bounding box in the frame turned about z by the principal direction of the points' horizontal
    coordinates (2D PCA), or not turned at all when ``fixed`` (the frame's axes are the room's).
    Returns (centers (H, 3), half-sizes (H, 3), yaw angles (H,)). Tensors (the CPU path is
    :func:`~cuboidcli.solvers.init_fused.upright_boxes`)."""
    import torch

    mean = points.mean(1)
    centred = points - mean[:, None]
    if fixed:
        yaw = torch.zeros(points.shape[0], dtype=points.dtype, device=points.device)
    else:
        x, y = centred[..., 0], centred[..., 1]
        yaw = 0.5 * torch.atan2(2.0 * (x * y).sum(1), (x * x).sum(1) - (y * y).sum(1))
    cos, sin = torch.cos(yaw), torch.sin(yaw)
    zero, one = torch.zeros_like(yaw), torch.ones_like(yaw)
    rot = torch.stack([cos, -sin, zero, sin, cos, zero, zero, zero, one], -1).reshape(-1, 3, 3)
    local = centred @ rot
    lo, hi = local.amin(1), local.amax(1)
    center = mean + (rot @ (0.5 * (lo + hi))[..., None])[..., 0]
    half = (0.5 * (hi - lo)).clamp(bounds.a_min, bounds.a_max)
    return center, half, yaw


@dataclass
class NumericalSolver:
    """PCA + Adam solver. ``lr`` and ``iters`` are the paper's 0.01 and 50 (NYU)."""

    bounds: SizeBounds = SizeBounds()
    lr: float = 0.01
    iters: int = 50
    backend: str = "auto"
    """auto (the fused numba loop; for sets on a GPU on a CPU copy, as the sets are tiny and Adam's
    sequential steps are launch-bound on a GPU) | numba | torch, the rule of a fit's scoring backend
    (:func:`~cuboidcli.geometry.backends.resolve_backend`; numba is refused on a GPU); "fused" is another
    name for numba."""
    name: str = "numerical"
    takes_numpy = True
    """Numpy sets are solved by the fused loop and give numpy boxes; tensors give tensors."""

    def objective(self, points: Tensor, center: Tensor, axis_angle: Tensor, half: Tensor) -> Tensor:
        """F summed over each set's points: (H,). points (H, C, 3). Tensors."""
        import torch

        from cuboidcli.geometry.kernels import cuboid_sq_distance

        R = axis_angle_to_matrix(axis_angle)
        local = torch.einsum("hck,hkj->hcj", points - center[:, None], R)
        d_sq = cuboid_sq_distance(local, half)  # Eq. 2 for per-hypothesis point sets: (H, C)
        return d_sq.sum(1) * half.sum(-1)

    def __call__(self, minimal_sets: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        if self._uses_numba(device_of(minimal_sets)):
            return self._solve_fused(minimal_sets)
        return self._solve_torch(minimal_sets)

    def _on_cpu(self, minimal_sets: Tensor) -> np.ndarray:
        """The sets as a float64 numpy array (copied from a GPU in "hybrid" mode: they are tiny)."""
        return np.ascontiguousarray(numpy64(minimal_sets))

    def solve_upright(self, minimal_sets: Tensor, fixed: bool = False) -> tuple[Tensor, Tensor, Tensor]:
        """Yaw-only boxes: ``minimal_sets`` (H, C, 3) in a frame whose z axis is up; every box turns about z
        only (``fixed``: not at all, the frame's axes are the room's). Same returns as ``__call__``, in that
        frame. One rotation parameter (or none) instead of three; a box on the room's axes converges in
        :data:`FIXED_AXES_ITERS` Adam steps."""
        pts = minimal_sets
        rot_dof = 0 if fixed else 1
        iters = min(self.iters, FIXED_AXES_ITERS) if fixed else self.iters
        if self._uses_numba(device_of(pts)):
            from cuboidcli.solvers.init_fused import upright_boxes

            sets = self._on_cpu(pts)
            init = np.empty((sets.shape[0], 9))
            upright_boxes(sets, self.bounds.a_min, self.bounds.a_max, fixed, init)
            return self._adam_fused(pts, init, rot_dof, iters)
        import torch

        pts = pts.detach()
        with torch.no_grad():
            c0, a0, yaw = upright_init(pts.double(), self.bounds, fixed)
            r0 = torch.zeros_like(c0)
            r0[:, 2] = yaw
        return self._adam_torch(pts, c0.to(pts.dtype), r0.to(pts.dtype), a0.to(pts.dtype), rot_dof, iters)

    def warm_up(self) -> None:
        """Compile (or load from numba's cache) the CPU kernels this solver runs, once per solver."""
        if getattr(self, "_warm", False) or not self._uses_numba("cpu"):
            return
        sets = np.array([[[0.0, 0.0, 2.0], [0.1, 0.0, 2.0], [0.0, 0.1, 2.1]]])
        self(sets)
        self.solve_upright(sets)  # yaw-only boxes; boxes on the room's axes share the kernels
        self._warm = True

    def _uses_numba(self, device) -> bool:
        """Whether sets on ``device`` are solved by the fused numba loop (else by torch)."""
        kind = resolve_backend("numba" if self.backend == "fused" else self.backend, device)
        return kind in ("numba", "hybrid")

    def _solve_fused(self, minimal_sets: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        from cuboidcli.solvers.init_fused import pca_boxes

        init = np.empty((minimal_sets.shape[0], 9))
        pca_boxes(self._on_cpu(minimal_sets), self.bounds.a_min, self.bounds.a_max, init)
        return self._adam_fused(minimal_sets, init, 3)

    def _adam_fused(self, pts: Tensor, init: np.ndarray, rot_dof: int, iters: int | None = None):
        """The fused CPU loop of :meth:`_adam_torch` from ``init`` (H, 9) = (centre, axis-angle,
        half-sizes) rows (float64 in; out of the kind, dtype and device of ``pts``)."""
        from cuboidcli.solvers.adam_fused import adam_solve, rotation_matrices

        out = init.copy()
        adam_solve(
            self._on_cpu(pts),
            init,
            self.bounds.a_min,
            self.bounds.a_max,
            self.lr,
            self.iters if iters is None else iters,
            out,
            rot_dof,
        )
        rot = np.empty((out.shape[0], 3, 3))
        rotation_matrices(out[:, 3:6].copy(), rot)
        ref = pts[:1, 0, 0]
        return like(out[:, :3], ref), like(out[:, 6:], ref), like(rot, ref)

    def _solve_torch(self, minimal_sets: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        import torch

        pts = minimal_sets.detach()
        with torch.no_grad():
            c0, a0, R0 = pca_init(pts, self.bounds)
            r0 = matrix_to_axis_angle(R0)
        return self._adam_torch(pts, c0, r0, a0, 3)

    def _adam_torch(
        self, pts: Tensor, c0: Tensor, r0: Tensor, a0: Tensor, rot_dof: int, iters: int | None = None
    ):
        """Adam from (c0, axis-angle r0, a0) for ``iters`` steps (default ``self.iters``), keeping the best
        iterate per hypothesis; ``rot_dof`` as in :func:`~cuboidcli.solvers.adam_fused.adam_solve`."""
        import torch

        iters = self.iters if iters is None else iters
        center = c0.clone().requires_grad_(True)
        rvec = r0.clone().requires_grad_(True)
        half = a0.clone().requires_grad_(True)
        opt = torch.optim.Adam([center, rvec, half], lr=self.lr)
        best_loss = torch.full((pts.shape[0],), float("inf"), dtype=pts.dtype, device=pts.device)
        best = [c0.clone(), r0.clone(), a0.clone()]
        with torch.enable_grad():
            for _ in range(iters + 1):
                loss = self.objective(pts, center, rvec, half)
                with torch.no_grad():
                    better = loss < best_loss
                    best_loss = torch.where(better, loss, best_loss)
                    for b, p in zip(best, (center, rvec, half), strict=True):
                        b.copy_(torch.where(better[:, None], p, b))
                if _ == iters:
                    break
                opt.zero_grad(set_to_none=True)
                loss.sum().backward()
                rvec.grad[:, : 3 - rot_dof] = 0.0
                opt.step()
                with torch.no_grad():
                    half.clamp_(self.bounds.a_min, self.bounds.a_max)
        c, r, a = best
        return c.detach(), a.detach(), axis_angle_to_matrix(r.detach())


def build(inputs) -> NumericalSolver:
    """The solver of the parts registry (``numerical``) from a ``BuildInputs``: the fit's size bounds, Adam's
    learning rate and steps, and its backend (``inputs.config``)."""
    c = inputs.config
    return NumericalSolver(bounds=SizeBounds.of(c), lr=c.solver_lr, iters=c.solver_iters, backend=c.backend)

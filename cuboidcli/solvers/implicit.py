"""Gradients of an iterative cuboid solver by the implicit function theorem (paper Sec. 3.5,
"Differentiable Solver"), as a custom autograd function.

The forward pass runs any :class:`~cuboidcli.solvers.base.CuboidSolver` (by default the numerical one,
PCA + Adam) on minimal sets ``(H, C, 3)`` without tracking its iterations. The backward pass treats the
result as a root of a per-point residual vector F(S, h) = 0 and differentiates that equation instead.

Which F. The paper writes F = d(h, y)^2 (a_x + a_y + a_z) per point (Eq. 8). Its derivatives are
2 d (a_x + a_y + a_z) times those of d, which all vanish when the points lie on the cuboid, exactly the
case the equation F = 0 describes; so we differentiate the residual whose square is that term,

    F_i(S, h) = sqrt(a_x + a_y + a_z) * s(h, y_i),        i = 1..C,

with s the *signed* point-to-surface distance (negative inside; s^2 = d^2 of Eq. 2), which is smooth
where a point lies on the inside of a face. ||F||^2 is the solver's objective for one set.

Which h. The rotation is parametrised locally, R = R_hat Exp([w]_x) with w = 0 at the solution, and
h = (w, t) (3 + 3). The paper's mask drops the sizes (dF/da is zero or nearly so, and 6 points on a box
do not determine its extent): they are held constant, the half-sizes output carries no gradient, and

    d(w, t) / dS = -(dF / d(w, t))^+ dF / dS          (J^+ the pseudo-inverse of the (C, 6) Jacobian).

With the sizes fixed the common factor sqrt(a_x + a_y + a_z) cancels in J^+ dF/dS, so this is also the
exact derivative of the pose that minimises sum_i s_i^2 when the points fit the box (zero residual), and
its Gauss-Newton approximation otherwise. For C = 6 the system is square and J^+ = J^-1 if it is regular.
Singular values below ``rtol`` times the largest are cut: poses the points do not determine (e.g. all
points on one face leave the in-plane pose free) receive no gradient instead of an exploding one.

The theorem needs the forward result to be a stationary point; Adam's 50 steps are not quite one.
:func:`refine_pose` (Gauss-Newton on (w, t) with the sizes fixed) polishes any result onto one.
"""

from __future__ import annotations

from collections.abc import Callable

import torch
from torch import Tensor
from torch.autograd.function import once_differentiable

from cuboidcli.geometry.rotations import axis_angle_to_matrix

Solver = Callable[[Tensor], tuple[Tensor, Tensor, Tensor]]

#: Relative cut-off of the pseudo-inverse's singular values (see the module docstring).
DEFAULT_RTOL = 1e-4


def signed_distance(local: Tensor, half_sizes: Tensor) -> Tensor:
    """Signed distance to the cuboid surface, m: local (..., 3) points in the cuboid frame, half_sizes
    broadcastable (..., 3) -> (...). Positive outside, negative inside; its square is Eq. 2.

    Written so that a point exactly on a face gets the face's gradient: the inside branch (max of
    |y_c| - a_c, which is 0 on the surface) is taken on the surface, and the outside norm is evaluated
    on a safe argument there so that ``torch.where`` does not mix a NaN gradient in.
    """
    q = local.abs() - half_sizes
    q_max = q.amax(-1)
    outside = q.clamp_min(0).square().sum(-1)
    is_out = q_max > 0
    return torch.where(is_out, torch.where(is_out, outside, torch.ones_like(outside)).sqrt(), q_max)


def pose_residuals(points: Tensor, centers: Tensor, half_sizes: Tensor, rotations: Tensor) -> Tensor:
    """F(S, h) of each set: points (H, C, 3), centers (H, 3), half_sizes (H, 3), rotations (H, 3, 3) ->
    (H, C), sqrt(m^3) (sqrt(a_x + a_y + a_z) times a signed distance)."""
    local = torch.einsum("hck,hkj->hcj", points - centers[:, None], rotations)
    return signed_distance(local, half_sizes[:, None]) * half_sizes.sum(-1, keepdim=True).sqrt()


def residual_jacobians(
    points: Tensor, centers: Tensor, half_sizes: Tensor, rotations: Tensor
) -> tuple[Tensor, Tensor, Tensor]:
    """F (H, C), dF/d(w, t) (H, C, 6) and the diagonal blocks dF_i/dy_i (H, C, 3) at the given cuboids.

    F_i depends on its own point only, through y_hat_i = Exp(-w) R_hat^T (y_i - t), so with g = ds/dy_hat
    (one batched autograd call): ds/dy = R g, ds/dt = -R g and, as d y_hat / dw = [y_hat]_x at w = 0,
    ds/dw = g x y_hat. dF/dS is block-diagonal; only its (C, 3) blocks are returned.
    """
    with torch.enable_grad():
        local = torch.einsum("hck,hkj->hcj", points - centers[:, None], rotations).detach().requires_grad_()
        s = signed_distance(local, half_sizes[:, None].detach())
        (g,) = torch.autograd.grad(s.sum(), local)
    scale = half_sizes.sum(-1).sqrt()[:, None, None]  # the common factor sqrt(a_x + a_y + a_z)
    j_pts = torch.einsum("hkj,hcj->hck", rotations, g) * scale
    j_rot = torch.linalg.cross(g, local.detach(), dim=-1) * scale
    return s.detach() * scale[..., 0], torch.cat([j_rot, -j_pts], -1), j_pts


def _cross_basis(like: Tensor) -> Tensor:
    """(3, 3, 3): entry k is the cross-product matrix [e_k]_x, the generator of rotations about axis k."""
    b = torch.zeros(3, 3, 3, dtype=like.dtype, device=like.device)
    for k in range(3):
        i, j = (k + 1) % 3, (k + 2) % 3
        b[k, j, i], b[k, i, j] = 1.0, -1.0  # [e_k]_x e_i = e_j for the cyclic triple (k, i, j)
    return b


def _retract(centers: Tensor, rotations: Tensor, step: Tensor) -> tuple[Tensor, Tensor]:
    """Apply a pose step (H, 6) = (w, dt): R <- R Exp(w), t <- t + dt."""
    return centers + step[:, 3:], rotations @ axis_angle_to_matrix(step[:, :3])


def refine_pose(
    points: Tensor, centers: Tensor, half_sizes: Tensor, rotations: Tensor, iters: int = 10
) -> tuple[Tensor, Tensor]:
    """Gauss-Newton on the pose (w, t) of each set with the half-sizes fixed, minimising ||F||^2.

    points (H, C, 3); centers (H, 3); half_sizes (H, 3); rotations (H, 3, 3). Returns refined
    ``(centers, rotations)``. A step that does not lower a set's cost is rejected and that set's next
    step is halved, so the cost never rises. No gradients are tracked.
    """
    with torch.no_grad():
        factor = torch.ones(points.shape[0], 1, dtype=points.dtype, device=points.device)
        cost = pose_residuals(points, centers, half_sizes, rotations).square().sum(-1)
        for _ in range(iters):
            f, j_pose, _ = residual_jacobians(points, centers, half_sizes, rotations)
            step = -(torch.linalg.pinv(j_pose) @ f[..., None])[..., 0] * factor
            new_c, new_r = _retract(centers, rotations, step)
            new_cost = pose_residuals(points, new_c, half_sizes, new_r).square().sum(-1)
            better = new_cost < cost
            centers = torch.where(better[:, None], new_c, centers)
            rotations = torch.where(better[:, None, None], new_r, rotations)
            cost = torch.where(better, new_cost, cost)
            factor = torch.where(better[:, None], torch.ones_like(factor), 0.5 * factor)
    return centers, rotations


class ImplicitCuboidSolve(torch.autograd.Function):
    """``apply(points (H, C, 3), solver, rtol)`` -> centers (H, 3), half_sizes (H, 3), rotations (H, 3, 3).

    Forward: ``solver(points)`` without tracking, cast to the points' dtype and device. Backward: the
    masked implicit-function gradient of the module docstring; half_sizes are non-differentiable.
    float32 or float64 (use float64 to compare with finite differences).
    """

    @staticmethod
    def forward(ctx, points: Tensor, solver: Solver, rtol: float) -> tuple[Tensor, Tensor, Tensor]:
        if points.ndim != 3 or points.shape[-1] != 3:
            raise ValueError(f"points must be (H, C, 3), got {tuple(points.shape)}")
        with torch.no_grad():
            out = solver(points.detach())
        centers, half_sizes, rotations = (x.to(dtype=points.dtype, device=points.device) for x in out)
        ctx.save_for_backward(points, centers, half_sizes, rotations)
        ctx.rtol = rtol
        ctx.mark_non_differentiable(half_sizes)
        return centers, half_sizes, rotations

    @staticmethod
    @once_differentiable
    def backward(ctx, grad_centers: Tensor, _grad_half: Tensor, grad_rotations: Tensor):
        points, centers, half_sizes, rotations = ctx.saved_tensors
        _, j_pose, j_pts = residual_jacobians(points, centers, half_sizes, rotations)
        # dL/dw_k at w = 0, with dR/dw_k = R_hat [e_k]_x: sum_ij G_ij (R_hat [e_k]_x)_ij
        basis = _cross_basis(points)
        grad_w = torch.einsum("hij,hil,klj->hk", grad_rotations, rotations, basis)
        grad_pose = torch.cat([grad_w, grad_centers], -1)  # (H, 6)
        # d pose / d y_i = -(J^+)[:, i] (dF_i/dy_i)^T, so dL/dy_i = -u_i dF_i/dy_i with u = J^+^T dL/dpose
        u = torch.einsum("hkc,hk->hc", torch.linalg.pinv(j_pose, rtol=ctx.rtol), grad_pose)
        return -u[..., None] * j_pts, None, None


def implicit_cuboid_solve(
    points: Tensor, solver: Solver | None = None, rtol: float = DEFAULT_RTOL
) -> tuple[Tensor, Tensor, Tensor]:
    """Fit one cuboid per minimal set with gradients to the points by the implicit function theorem.

    points (H, C, 3) m; ``solver`` any CuboidSolver (default: ``NumericalSolver()``). Returns centers
    (H, 3), half_sizes (H, 3) (no gradient: the paper's mask), rotations (H, 3, 3).
    """
    if solver is None:
        from cuboidcli.solvers.numerical import NumericalSolver

        solver = NumericalSolver()
    return ImplicitCuboidSolve.apply(points, solver, rtol)


def polished(solver: Solver, iters: int = 10) -> Solver:
    """``solver`` followed by :func:`refine_pose`, so that its result is a stationary point of the pose."""

    def run(points: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        centers, half_sizes, rotations = solver(points)
        centers, rotations = refine_pose(points, centers, half_sizes, rotations, iters)
        return centers, half_sizes, rotations

    return run

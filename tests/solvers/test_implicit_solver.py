"""Implicit-function gradients of the cuboid solver (paper Sec. 3.5) against finite differences."""

from __future__ import annotations

import pytest
import torch

from cuboidcli.geometry.kernels import cuboid_sq_distance
from cuboidcli.geometry.rotations import axis_angle_to_matrix
from cuboidcli.solvers.implicit import (
    implicit_cuboid_solve,
    polished,
    pose_residuals,
    refine_pose,
    residual_jacobians,
    signed_distance,
)
from cuboidcli.solvers.numerical import NumericalSolver

F64 = torch.float64


pytestmark = pytest.mark.usefixtures("one_thread")


def box_on_three_faces(per_face: int, seed: int = 0, dtype=F64):
    """Points exactly on the -x, -y and -z faces (inside each face, away from its edges) of a rotated box:
    points (1, 3 * per_face, 3) and the box (centers (1, 3), half_sizes (1, 3), rotations (1, 3, 3))."""
    g = torch.Generator().manual_seed(seed)
    half = torch.tensor([0.4, 0.25, 0.3], dtype=dtype)
    R = axis_angle_to_matrix(torch.tensor([0.3, -0.5, 0.2], dtype=dtype))  # noqa: N806
    t = torch.tensor([0.2, -0.1, 3.0], dtype=dtype)
    faces = []
    for axis in range(3):
        local = torch.zeros(per_face, 3, dtype=dtype)
        local[:, axis] = -half[axis]
        for other in {0, 1, 2} - {axis}:
            local[:, other] = (torch.rand(per_face, generator=g, dtype=dtype) * 1.4 - 0.7) * half[other]
        faces.append(local @ R.T + t)
    return torch.cat(faces)[None], t[None], half[None], R[None]


def pose_outputs(solver):
    """(centers, rotations) of the implicit solve: the outputs whose gradient the paper's mask keeps."""

    def run(points):
        centers, _, rotations = implicit_cuboid_solve(points, solver)
        return centers, rotations

    return run


def central_differences(fn, points, eps=1e-6):
    """d(flattened outputs)/d(flattened points) by central differences: (outputs, 3 C)."""
    flat = points.reshape(-1)
    cols = []
    for k in range(flat.numel()):
        step = torch.zeros_like(flat)
        step[k] = eps
        plus = torch.cat([o.reshape(-1) for o in fn((flat + step).reshape(points.shape))])
        minus = torch.cat([o.reshape(-1) for o in fn((flat - step).reshape(points.shape))])
        cols.append((plus - minus) / (2 * eps))
    return torch.stack(cols, 1)


def backprop_jacobian(fn, points):
    """The same Jacobian from the custom backward, one output at a time."""
    x = points.clone().requires_grad_(True)
    out = torch.cat([o.reshape(-1) for o in fn(x)])
    rows = [torch.autograd.grad(out[i], x, retain_graph=True)[0].reshape(-1) for i in range(out.numel())]
    return torch.stack(rows)


def test_signed_distance_squares_to_eq2():
    g = torch.Generator().manual_seed(1)
    local = torch.randn(1, 200, 3, generator=g, dtype=F64) * 0.6
    half = torch.tensor([[0.4, 0.25, 0.3]], dtype=F64)
    s = signed_distance(local, half[:, None])
    torch.testing.assert_close(s.square(), cuboid_sq_distance(local, half))
    inside = (local.abs() < half[:, None]).all(-1)
    assert (s[inside] < 0).all() and (s[~inside] > 0).all()


def test_hand_written_jacobians_match_torch_func():
    """dF/d(w, t) and dF/dy of :func:`residual_jacobians` against jacrev of F with R = R_hat Exp(w)."""
    from torch.func import jacrev

    points, t, half, R = box_on_three_faces(3)  # noqa: N806
    g = torch.Generator().manual_seed(2)
    points = points + 0.01 * torch.randn(points.shape, generator=g, dtype=F64)  # inside and outside

    def residuals(pose, pts):
        rot = R[0] @ axis_angle_to_matrix(pose[:3])
        return pose_residuals(pts[None], t[0] + pose[3:][None], half, rot[None])[0]

    pose0 = torch.zeros(6, dtype=F64)
    f, j_pose, j_pts = residual_jacobians(points, t, half, R)
    torch.testing.assert_close(f[0], residuals(pose0, points[0]))
    torch.testing.assert_close(j_pose[0], jacrev(residuals, argnums=0)(pose0, points[0]))
    full = jacrev(residuals, argnums=1)(pose0, points[0])  # (C, C, 3), block-diagonal
    torch.testing.assert_close(j_pts[0], torch.einsum("iik->ik", full))


@pytest.mark.parametrize("per_face", [2, 4])
def test_pose_gradient_matches_finite_differences(per_face):
    """A solver run to convergence: Gauss-Newton on the pose from the true box, sizes held at the true ones
    (exactly what the mask assumes). C = 6 is the paper's minimal set (square system), C = 12 is
    overdetermined. Tolerance: central differences with eps = 1e-6 are exact to ~1e-12 here, the re-solve
    converges to ~1e-15 (1e-9 after dividing by eps); for C = 12 the perturbed points no longer fit the
    box exactly and the pseudo-inverse drops terms of the order of that residual, O(eps) ~ 1e-6."""
    points, t, half, R = box_on_three_faces(per_face)  # noqa: N806
    solver = pose_outputs(lambda p: (lambda c, r: (c, half, r))(*refine_pose(p, t, half, R, iters=3)))
    analytic = backprop_jacobian(solver, points)
    numeric = central_differences(solver, points)
    assert numeric.abs().max() > 0.1  # the pose does move with the points
    torch.testing.assert_close(analytic, numeric, atol=1e-5, rtol=1e-4)


def test_numerical_solver_gradient_matches_frozen_size_differences():
    """The NumericalSolver (PCA + Adam, run to convergence: 300 steps), polished to a stationary pose, on a
    minimal set exactly on three faces. Adam shrinks the box toward the visible corner (the sizes are
    ambiguous), so the reference re-solves the pose with the sizes it found held fixed: d(R, t)/dS with
    the sizes masked. (Differences through Adam itself are meaningless: its normalised steps are not a
    smooth function of the points.)"""
    points, *_ = box_on_three_faces(2, seed=1)
    solver = polished(NumericalSolver(iters=300), iters=8)
    centers, half, rotations = solver(points)
    assert pose_residuals(points, centers, half, rotations).abs().max() < 1e-9  # it fits

    def frozen(p):
        c, r = refine_pose(p, centers, half, rotations, iters=3)
        return c, r

    analytic = backprop_jacobian(pose_outputs(solver), points)
    torch.testing.assert_close(analytic, central_differences(frozen, points), atol=1e-5, rtol=1e-4)


def test_gradient_flows_to_points_float32():
    g = torch.Generator().manual_seed(0)
    sets = torch.cat([box_on_three_faces(2, seed=s, dtype=torch.float32)[0] for s in range(4)])
    points = (sets + 0.002 * torch.randn(sets.shape, generator=g)).requires_grad_(True)
    centers, half, rotations = implicit_cuboid_solve(points)
    assert not half.requires_grad  # the paper's mask: no size gradient
    loss = centers.square().sum() + (rotations * torch.arange(9.0).view(3, 3)).sum()
    loss.backward()
    assert points.grad.shape == points.shape and points.grad.dtype == torch.float32
    assert torch.isfinite(points.grad).all() and points.grad.abs().sum() > 0


def test_translation_gradient_of_a_shift_is_identity():
    """Moving every point by d moves the box by d: sum_i dt/dy_i = I (with the sizes held)."""
    points, t, half, R = box_on_three_faces(4)  # noqa: N806
    solver = pose_outputs(lambda p: (lambda c, r: (c, half, r))(*refine_pose(p, t, half, R, iters=3)))
    jac = backprop_jacobian(lambda p: solver(p)[:1], points)  # (3, 3 C)
    torch.testing.assert_close(jac.reshape(3, -1, 3).sum(1), torch.eye(3, dtype=F64), atol=1e-9, rtol=0)


def test_underdetermined_pose_gets_bounded_gradient():
    """All points on one face leave the in-plane pose free; the cut pseudo-inverse keeps gradients finite."""
    points, t, half, R = box_on_three_faces(6)  # noqa: N806
    one_face = points[:, :6].clone().requires_grad_(True)
    centers, _, rotations = implicit_cuboid_solve(one_face, lambda p: (t, half, R))
    (centers.sum() + rotations.sum()).backward()
    assert torch.isfinite(one_face.grad).all() and one_face.grad.abs().max() < 100


def test_rejects_bad_shapes():
    with pytest.raises(ValueError, match=r"\(H, C, 3\)"):
        implicit_cuboid_solve(torch.zeros(6, 3))

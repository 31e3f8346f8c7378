import numpy as np
import pytest
import torch

from cuboidcli.geometry.kernels import cuboid_sq_distance, to_local
from cuboidcli.geometry.rotations import axis_angle_to_matrix
from cuboidcli.solvers.adam_fused import objective_and_grad
from cuboidcli.solvers.base import SizeBounds
from cuboidcli.solvers.numerical import NumericalSolver, pca_init


def box_face_points(center, half, R, n_per_face=3, seed=0):
    """Points on the three camera-facing sides of a box (camera at the origin)."""
    rng = np.random.default_rng(seed)
    pts = []
    cam_local = -R.T @ center
    for axis in range(3):
        sign = 1.0 if cam_local[axis] > half[axis] else -1.0
        for _ in range(n_per_face):
            p = rng.uniform(-1, 1, 3) * half
            p[axis] = sign * half[axis]
            pts.append(R @ p + center)
    return np.array(pts)


def test_pca_init_centres_the_bounding_box():
    # six points of an axis-aligned 2 x 1 x 0 m rectangle with an off-centre mean
    pts = torch.tensor(
        [
            [
                [-1.0, -0.5, 3.0],
                [1.0, -0.5, 3.0],
                [1.0, 0.5, 3.0],
                [-1.0, 0.5, 3.0],
                [0.9, 0.0, 3.0],
                [0.7, 0.0, 3.0],
            ]
        ],
        dtype=torch.float64,
    )
    c, a, R = pca_init(pts, SizeBounds())
    assert torch.allclose(c, torch.tensor([[0.0, 0.0, 3.0]], dtype=torch.float64), atol=1e-9)
    assert torch.allclose(a.sort().values, torch.tensor([[1e-3, 0.5, 1.0]], dtype=torch.float64), atol=1e-9)
    assert torch.linalg.det(R).item() == pytest.approx(1.0)


def test_pca_init_centres_the_bounding_box_of_a_rotated_set():
    """A rotated, off-centre set whose principal axes are the box's axes: the box centre comes back only if
    the PCA-frame offset is mapped back with V (not V^T, the research code's bug; here V != V^T)."""
    local = torch.tensor(
        [
            [-1.0, -0.5, 0.0],
            [1.0, -0.5, 0.0],
            [1.0, 0.5, 0.0],
            [-1.0, 0.5, 0.0],
            [0.9, 0.0, 0.0],
            [0.7, 0.0, 0.0],
            [0.3, 0.0, 0.2],
            [0.3, 0.0, -0.2],
        ],
        dtype=torch.float64,
    )  # covariance diagonal in the box frame, mean off the box centre along x
    rot = axis_angle_to_matrix(torch.tensor([0.4, -0.9, 0.6], dtype=torch.float64))
    assert (rot - rot.T).abs().max() > 0.5  # far from symmetric
    center = torch.tensor([0.3, -0.2, 3.0], dtype=torch.float64)
    pts = (local @ rot.T + center)[None]
    for solver_input in (pts, pts.float()):
        c, a, R = pca_init(solver_input, SizeBounds())
        tol = 1e-9 if solver_input.dtype == torch.float64 else 1e-5
        torch.testing.assert_close(c[0].double(), center, atol=tol, rtol=0)
        torch.testing.assert_close(
            a[0].double(), torch.tensor([1.0, 0.5, 0.2], dtype=torch.float64), atol=tol, rtol=0
        )
        # the columns are the box axes up to sign, and R is a proper rotation
        cos = (R[0].double().T @ rot).abs()
        torch.testing.assert_close(cos, torch.eye(3, dtype=torch.float64), atol=1e-5, rtol=0)
        assert torch.linalg.det(R[0].double()).item() == pytest.approx(1.0)


def test_fused_gradient_equals_autograd():
    g = torch.Generator().manual_seed(0)
    solver = NumericalSolver(backend="torch")
    for _ in range(5):
        pts = torch.randn(1, 6, 3, generator=g, dtype=torch.float64) * 0.5 + torch.tensor([0, 0, 3.0])
        params = [
            torch.randn(1, 3, generator=g, dtype=torch.float64) * s + o
            for s, o in ((0.2, torch.tensor([0, 0, 3.0])), (1.0, 0.0), (0.2, 0.4))
        ]
        params = [p.requires_grad_(True) for p in params]
        f = solver.objective(pts, *params).sum()
        f.backward()
        ref = torch.cat([p.grad[0] for p in params]).numpy()
        f2, g2 = objective_and_grad(pts[0].numpy(), torch.cat([p[0] for p in params]).detach().numpy())
        assert f2 == pytest.approx(f.item(), rel=1e-12)
        np.testing.assert_allclose(g2, ref, rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize("backend", ["fused", "torch"])
def test_solver_recovers_a_box_from_its_visible_sides(backend):
    R = axis_angle_to_matrix(torch.tensor([0.1, 0.5, -0.05], dtype=torch.float64)).numpy()
    center, half = np.array([0.3, 0.2, 3.0]), np.array([0.4, 0.3, 0.5])
    pts = torch.from_numpy(box_face_points(center, half, R, 2)).float()[None]
    c, a, Rs = NumericalSolver(backend=backend, iters=200)(pts)
    d2 = cuboid_sq_distance(to_local(pts[0], c, Rs), a)
    assert d2.max().item() < 1e-4  # every point within 1 cm of the fitted surface
    assert (a >= 1e-3).all() and (a <= 2.0).all()
    assert torch.allclose(Rs @ Rs.transpose(-1, -2), torch.eye(3).expand(1, 3, 3), atol=1e-5)


def test_backends_agree_and_keep_best_iterate_per_hypothesis():
    g = torch.Generator().manual_seed(1)
    pts = torch.randn(64, 6, 3, generator=g) * 0.4 + torch.tensor([0.0, 0.0, 3.0])
    fused = NumericalSolver(backend="fused")
    torch_s = NumericalSolver(backend="torch")
    c1, a1, R1 = fused(pts)
    c2, a2, R2 = torch_s(pts)
    close = ((c1 - c2).norm(dim=-1) < 1e-3) & ((a1 - a2).abs().amax(-1) < 1e-3)
    assert close.float().mean() > 0.95
    # the best iterate is never worse than the initial guess, hypothesis by hypothesis
    c0, a0, R0 = pca_init(pts, fused.bounds)
    from cuboidcli.geometry.rotations import matrix_to_axis_angle

    f0 = fused.objective(pts, c0, matrix_to_axis_angle(R0), a0)
    f1 = fused.objective(pts, c1, matrix_to_axis_angle(R1), a1)
    assert (f1 <= f0 + 1e-5).all()


def test_refinement_gradient_equals_autograd_and_removes_slab_bias():
    from cuboidcli.fitting.refine import refine_cuboid_fused
    from cuboidcli.geometry import kernels as K
    from cuboidcli.geometry.adam import oa_objective_and_grad

    g = torch.Generator().manual_seed(5)
    for _ in range(4):
        pts = torch.randn(40, 3, generator=g, dtype=torch.float64) * 0.5 + torch.tensor([0.0, 0.0, 3.0])
        c = (
            torch.randn(3, generator=g, dtype=torch.float64) * 0.2 + torch.tensor([0.0, 0.0, 3.0])
        ).requires_grad_()
        r = torch.randn(3, generator=g, dtype=torch.float64).requires_grad_()
        a = (torch.rand(3, generator=g, dtype=torch.float64) * 0.5 + 0.1).requires_grad_()
        f = K.oa_sq_distance(pts, c[None], a[None], axis_angle_to_matrix(r)[None]).mean()
        f.backward()
        f2, g2 = oa_objective_and_grad(pts.numpy(), torch.cat([c, r, a]).detach().numpy())
        assert f2 == pytest.approx(f.item(), rel=1e-10)
        np.testing.assert_allclose(g2, torch.cat([c.grad, r.grad, a.grad]).numpy(), rtol=1e-8, atol=1e-12)
    # a wall at z = 3 with its points on the FAR face of a 6 cm slab: refinement moves the near face there
    rng = np.random.default_rng(0)
    wall = np.stack([rng.uniform(-1, 1, 500), rng.uniform(-1, 1, 500), np.full(500, 3.0)], -1)
    c2, a2, R2 = refine_cuboid_fused(
        wall, np.array([0.0, 0.0, 2.97]), np.array([1.0, 1.0, 0.03]), np.eye(3), 1e-3, 2.0, iters=100
    )
    near_face_z = c2[2] - a2[2]
    assert abs(near_face_z - 3.0) < 0.005


def test_solver_backend_follows_the_scoring_backend_rule(monkeypatch):
    """auto = the fused numba loop on the CPU; "numba" is the fused loop by the scoring backends' name and
    is refused for sets off the CPU (meta tensors stand in for a GPU), for free and upright boxes alike."""
    import cuboidcli.solvers.numerical as numerical

    g = torch.Generator().manual_seed(2)
    pts = torch.randn(8, 6, 3, generator=g) * 0.3 + torch.tensor([0.0, 0.0, 3.0])
    used = []
    for name in ("_adam_fused", "_adam_torch"):

        def spy(self, *args, _name=name, _inner=getattr(numerical.NumericalSolver, name)):
            used.append(_name)
            return _inner(self, *args)

        monkeypatch.setattr(numerical.NumericalSolver, name, spy)
    for backend, expected in (("auto", "_adam_fused"), ("numba", "_adam_fused"), ("torch", "_adam_torch")):
        used.clear()
        NumericalSolver(backend=backend)(pts)
        NumericalSolver(backend=backend).solve_upright(pts)
        assert used == [expected, expected], backend
    numba, fused = NumericalSolver(backend="numba")(pts), NumericalSolver(backend="fused")(pts)
    assert all(torch.equal(x, y) for x, y in zip(numba, fused, strict=True))
    for backend in ("numba", "fused"):
        with pytest.raises(ValueError, match="CPU only"):
            NumericalSolver(backend=backend)(pts.to("meta"))
        with pytest.raises(ValueError, match="CPU only"):
            NumericalSolver(backend=backend).solve_upright(pts.to("meta"))

"""The CPU initial boxes (numba) must equal the torch reference initialisation."""

import numpy as np
import torch

from cuboidcli.geometry.rotations import axis_angle_to_matrix
from cuboidcli.solvers.base import SizeBounds
from cuboidcli.solvers.init_fused import _sym_eig3, pca_boxes, upright_boxes
from cuboidcli.solvers.numerical import pca_init, upright_init


def sets(n=200, seed=0):
    g = torch.Generator().manual_seed(seed)
    stretch = torch.rand(n, 1, 3, generator=g, dtype=torch.float64) * 1.5 + 0.05
    pts = torch.randn(n, 6, 3, generator=g, dtype=torch.float64) * stretch
    rot = axis_angle_to_matrix(torch.randn(n, 3, generator=g, dtype=torch.float64))
    return pts @ rot.transpose(-1, -2) + torch.tensor([0.2, -0.1, 3.0], dtype=torch.float64)


def test_symmetric_eigen_decomposition():
    rng = np.random.default_rng(0)
    for _ in range(50):
        m = rng.normal(size=(3, 3))
        a = m @ m.T
        V, w = np.empty((3, 3)), np.empty(3)
        _sym_eig3(a.copy(), V, w)
        np.testing.assert_allclose(a @ V, V * w, atol=1e-10)
        np.testing.assert_allclose(V.T @ V, np.eye(3), atol=1e-12)
        assert w[0] >= w[1] >= w[2]
        np.testing.assert_allclose(w, np.sort(np.linalg.eigvalsh(a))[::-1], rtol=1e-10)


def test_pca_boxes_equal_the_reference():
    pts = sets()
    b = SizeBounds()
    out = np.empty((pts.shape[0], 9))
    pca_boxes(pts.numpy(), b.a_min, b.a_max, out)
    c, a, R = pca_init(pts, b)
    np.testing.assert_allclose(out[:, :3], c.numpy(), atol=1e-9)
    np.testing.assert_allclose(out[:, 6:], a.numpy(), atol=1e-9)
    np.testing.assert_allclose(
        axis_angle_to_matrix(torch.from_numpy(out[:, 3:6])).numpy(), R.numpy(), atol=1e-9
    )
    assert np.allclose(np.linalg.det(R.numpy()), 1.0)


def test_upright_boxes_equal_the_reference():
    pts = sets(seed=1)
    b = SizeBounds()
    for fixed in (False, True):
        out = np.empty((pts.shape[0], 9))
        upright_boxes(pts.numpy(), b.a_min, b.a_max, fixed, out)
        c, a, yaw = upright_init(pts, b, fixed)
        np.testing.assert_allclose(out[:, :3], c.numpy(), atol=1e-12)
        np.testing.assert_allclose(out[:, 6:], a.numpy(), atol=1e-12)
        np.testing.assert_allclose(out[:, 5], yaw.numpy(), atol=1e-12)
        assert (out[:, 3:5] == 0).all()

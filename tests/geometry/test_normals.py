"""Normals by local PCA in numba loops against Open3D's, and their degenerate cases."""

import numpy as np
import pytest

from cuboidcli.geometry.normals import estimate_normals_pca


def _open3d_normals(points: np.ndarray, radius: float, max_nn: int) -> np.ndarray:
    import open3d as o3d

    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    pcd.estimate_normals(o3d.geometry.KDTreeSearchParamHybrid(radius=radius, max_nn=max_nn))
    return np.asarray(pcd.normals)


def _room_like(seed: int) -> np.ndarray:
    """Points on the faces of a box room and a tilted slab, with 3 mm noise."""
    rng = np.random.default_rng(seed)
    parts = []
    for axis in range(3):
        for side in (0.0, 1.0):
            p = rng.random((1500, 3)) * [4.0, 3.0, 2.5]
            p[:, axis] = side * [4.0, 3.0, 2.5][axis]
            parts.append(p)
    u, v = rng.random((2, 800))
    a, b = np.array([1.0, 0.3, 0.2]), np.array([-0.2, 0.5, 0.9])
    parts.append(np.array([1.5, 1.0, 0.8]) + u[:, None] * a + v[:, None] * b)
    return np.concatenate(parts) + rng.normal(scale=0.003, size=(9800, 3))


@pytest.mark.parametrize("seed", [0, 1])
@pytest.mark.parametrize(("radius", "max_nn"), [(0.15, 24), (0.3, 10), (0.12, 50)])
def test_the_normals_are_open3d_s(seed, radius, max_nn):
    pts = _room_like(seed)
    ours, theirs = estimate_normals_pca(pts, radius, max_nn), _open3d_normals(pts, radius, max_nn)
    has = np.linalg.norm(ours, axis=1) > 0
    assert np.allclose(np.linalg.norm(ours[has], axis=1), 1.0, atol=1e-12)
    # where fewer than 3 neighbours lie within the radius Open3D puts (0, 0, 1), we put none
    assert has.mean() > 0.95 and np.array_equal(theirs[~has], np.tile([0.0, 0.0, 1.0], ((~has).sum(), 1)))
    # the same direction up to sign (ties among the farthest neighbours are the only freedom)
    agree = np.abs((ours[has] * theirs[has]).sum(1))
    assert np.median(agree) > 1 - 1e-12 and np.mean(agree > 1 - 1e-9) > 0.999


def test_a_plane_s_normal_and_a_slab_s():
    g = np.linspace(0, 1, 21)
    a, b = np.meshgrid(g, g)
    plane = np.c_[a.ravel(), b.ravel(), 0.3 * a.ravel()]  # the plane z = 0.3 x
    n = estimate_normals_pca(plane, 0.12)
    want = np.array([-0.3, 0.0, 1.0]) / np.hypot(0.3, 1.0)
    assert np.allclose(np.abs(n @ want), 1.0, atol=1e-12)


def test_fewer_than_three_neighbours_give_no_normal():
    pts = np.array([[0.0, 0, 0], [0.05, 0, 0], [5.0, 0, 0], [5.0, 0.05, 0], [5.0, 0, 0.05]])
    n = estimate_normals_pca(pts, 0.1)
    assert np.array_equal(n[:2], np.zeros((2, 3)))
    assert np.allclose(np.abs(n[2:, 0]), 1.0)  # the plane x = 5


def test_points_on_a_line_give_a_direction_across_it():
    d = np.array([1.0, 2.0, -0.5]) / np.linalg.norm([1.0, 2.0, -0.5])
    pts = np.linspace(0, 1, 30)[:, None] * d
    n = estimate_normals_pca(pts, 0.2)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0) and np.abs(n @ d).max() < 1e-9
    on_axis = np.c_[np.linspace(0, 1, 30), np.zeros(30), np.zeros(30)]  # a diagonal covariance
    n = estimate_normals_pca(on_axis, 0.2)
    assert np.allclose(np.linalg.norm(n, axis=1), 1.0) and np.abs(n[:, 0]).max() < 1e-12
    same = np.zeros((5, 3))  # one point five times: no spread at all
    assert np.array_equal(estimate_normals_pca(same, 0.1), np.zeros((5, 3)))


def test_the_nearest_neighbours_are_kept():
    # a point with 23 neighbours on the plane z = 0 and one more 4.5 cm away, 2 cm above it
    g = np.arange(-2, 3) * 0.01
    a, b = np.meshgrid(g, g)
    plane = np.c_[a.ravel(), b.ravel(), np.zeros(a.size)]
    plane = plane[np.argsort(np.linalg.norm(plane, axis=1), kind="stable")][:24]
    pts = np.concatenate([plane, [[0.04, 0.0, 0.02]]])
    assert abs(estimate_normals_pca(pts, 1.0)[0, 2]) == pytest.approx(1.0, abs=1e-12)
    assert abs(estimate_normals_pca(pts, 1.0, max_nn=25)[0, 2]) < 1 - 1e-6
    # the radius bounds the neighbours as well: the far point is not one at 4 cm
    assert abs(estimate_normals_pca(pts, 0.04, max_nn=25)[0, 2]) == pytest.approx(1.0, abs=1e-12)


def test_a_huge_extent_costs_no_memory_and_bad_settings_are_refused():
    rng = np.random.default_rng(2)
    patch = rng.random((200, 3)) * [0.2, 0.2, 0.0]
    pts = np.concatenate([patch, patch + [1e5, 1e5, 1e5]])  # 10^18 cells of 1 cm if stored densely
    n = estimate_normals_pca(pts, 0.05)
    assert np.allclose(np.abs(n[:, 2]), 1.0)
    assert estimate_normals_pca(np.zeros((0, 3)), 0.1).shape == (0, 3)
    for radius, nn in ((0.0, 24), (float("nan"), 24), (0.1, 2)):
        with pytest.raises(ValueError, match="radius_m must be > 0"):
            estimate_normals_pca(pts, radius, nn)

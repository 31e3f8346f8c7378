"""The array helpers a fit shares between numpy arrays and tensors, and the rotations on both kinds."""

import numpy as np
import pytest
import torch

from cuboidcli.geometry import arrays
from cuboidcli.geometry.inlier import combine
from cuboidcli.geometry.rotations import (
    axis_angle_to_matrix,
    matrix_to_axis_angle,
    matrix_to_quaternion,
    quaternion_to_matrix,
)


def test_categorical_draws_in_proportion_and_never_an_entry_of_weight_zero():
    p = np.array([0.0, 0.5, 0.0, 0.3, 0.2, 0.0])
    draws = arrays.categorical(p, 200_000, np.random.default_rng(3))
    assert draws.dtype == np.int64 and set(np.unique(draws)) == {1, 3, 4}
    np.testing.assert_allclose(np.bincount(draws, minlength=6) / draws.size, p, atol=0.005)
    again = arrays.categorical(p, 200_000, np.random.default_rng(3))
    np.testing.assert_array_equal(draws, again)  # deterministic for a seed
    # a total rounded below 1 and a last entry of weight 0: no draw lands past the last drawable entry
    tail = np.array([0.3, 0.7 - 1e-12, 0.0])
    assert arrays.categorical(tail, 10_000, np.random.default_rng(0)).max() == 1


def test_the_generator_follows_the_kind_of_the_data():
    assert isinstance(arrays.generator(0, np.zeros(3)), np.random.Generator)
    gen = arrays.generator(0, torch.zeros(3))
    assert isinstance(gen, torch.Generator)
    # a torch generator draws what torch drew before: the fits on tensors keep their cuboids
    expected = torch.randperm(50, generator=torch.Generator().manual_seed(0))
    assert torch.equal(arrays.randperm(50, gen), expected)
    assert isinstance(arrays.randperm(50, np.random.default_rng(0)), np.ndarray)


@pytest.mark.parametrize("kind", ["numpy", "torch"])
def test_combine_keeps_the_minimum_of_negatives_else_the_maximum(kind):
    new = np.array([0.2, -0.3, 0.9, -0.1])
    old = np.array([0.5, 0.4, -0.2, -0.6])
    if kind == "torch":
        new, old = torch.from_numpy(new), torch.from_numpy(old)
    out = combine(new, old)
    assert type(out) is type(new)
    np.testing.assert_array_equal(np.asarray(out), [0.5, -0.3, -0.2, -0.6])


def test_rotations_give_the_same_on_numpy_arrays_and_tensors():
    rng = np.random.default_rng(1)
    r = rng.normal(size=(200, 3)) * rng.uniform(0.0, 3.1, (200, 1))
    r[:3] *= 1e-7  # near the identity: the series branch
    R = axis_angle_to_matrix(r)
    assert isinstance(R, np.ndarray) and R.shape == (200, 3, 3)
    np.testing.assert_allclose(R, axis_angle_to_matrix(torch.from_numpy(r)).numpy(), atol=1e-14)
    np.testing.assert_allclose(R @ R.transpose(0, 2, 1), np.broadcast_to(np.eye(3), R.shape), atol=1e-12)
    q = matrix_to_quaternion(R)
    np.testing.assert_allclose(q, matrix_to_quaternion(torch.from_numpy(R)).numpy(), atol=1e-14)
    assert (q[:, 0] >= 0).all()
    np.testing.assert_allclose(quaternion_to_matrix(q), R, atol=1e-12)
    np.testing.assert_allclose(axis_angle_to_matrix(matrix_to_axis_angle(R)), R, atol=1e-12)
    one = matrix_to_axis_angle(R[5])  # a single matrix, no batch axis
    np.testing.assert_allclose(one, matrix_to_axis_angle(R)[5], atol=1e-15)

import math

import torch

from cuboidcli.geometry.rotations import (
    axis_angle_to_matrix,
    matrix_to_axis_angle,
    matrix_to_quaternion,
    matrix_to_rotation_6d,
    quaternion_to_matrix,
    rotation_6d_to_matrix,
)


def test_axis_angle_known_values():
    R = axis_angle_to_matrix(torch.tensor([0.0, 0.0, math.pi / 2], dtype=torch.float64))
    expected = torch.tensor([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]], dtype=torch.float64)
    assert torch.allclose(R, expected, atol=1e-12)
    assert torch.allclose(
        axis_angle_to_matrix(torch.zeros(3, dtype=torch.float64)), torch.eye(3, dtype=torch.float64)
    )


def test_quaternion_known_value_and_sign():
    # 90 degrees about x: q = (cos 45, sin 45, 0, 0)
    R = axis_angle_to_matrix(torch.tensor([math.pi / 2, 0.0, 0.0], dtype=torch.float64))
    q = matrix_to_quaternion(R)
    s = math.sqrt(0.5)
    assert torch.allclose(q, torch.tensor([s, s, 0.0, 0.0], dtype=torch.float64), atol=1e-12)
    assert torch.allclose(quaternion_to_matrix(-q), R, atol=1e-12)


def test_round_trips_batched_float32_and_float64():
    g = torch.Generator().manual_seed(0)
    for dtype, tol in ((torch.float64, 1e-9), (torch.float32, 1e-4)):
        r = torch.randn(200, 3, generator=g, dtype=torch.float64).to(dtype)
        r = r * (3.0 / r.norm(dim=-1, keepdim=True)).clamp(max=1.0)  # angles below pi
        R = axis_angle_to_matrix(r)
        assert torch.allclose(R @ R.transpose(-1, -2), torch.eye(3, dtype=dtype).expand_as(R), atol=tol)
        assert torch.allclose(torch.linalg.det(R), torch.ones(200, dtype=dtype), atol=tol)
        assert torch.allclose(matrix_to_axis_angle(R), r, atol=tol * 10)
        assert torch.allclose(quaternion_to_matrix(matrix_to_quaternion(R)), R, atol=tol)
        assert torch.allclose(rotation_6d_to_matrix(matrix_to_rotation_6d(R)), R, atol=tol)


def test_6d_gram_schmidt_of_non_orthogonal_input():
    x = torch.tensor([2.0, 0.0, 0.0, 1.0, 3.0, 0.0], dtype=torch.float64)
    assert torch.allclose(rotation_6d_to_matrix(x), torch.eye(3, dtype=torch.float64), atol=1e-12)


def test_gradcheck_rotations():
    r = torch.tensor([[0.3, -0.2, 0.5], [1e-6, 2e-6, -1e-6]], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(axis_angle_to_matrix, (r,))
    x = torch.randn(4, 6, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(rotation_6d_to_matrix, (x,))
    q = torch.randn(4, 4, dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(quaternion_to_matrix, (q,))

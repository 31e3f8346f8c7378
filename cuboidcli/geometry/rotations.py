"""Rotation representations, batched over leading dimensions, on numpy arrays or torch tensors alike
(differentiable on tensors).

Conventions: rotation matrices act on column vectors; the columns of ``R`` are the cuboid's local axes
expressed in camera coordinates. Quaternions are (w, x, y, z) with w >= 0. The 6D representation of
Zhou et al. (CVPR 2019) is the first two columns of ``R`` stacked as (r00, r10, r20, r01, r11, r21).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np

from cuboidcli.geometry.arrays import clamp, is_tensor, namespace

if TYPE_CHECKING:
    from torch import Tensor


def _skew(v: Tensor) -> Tensor:
    """(..., 3) -> (..., 3, 3) cross-product matrix [v]_x."""
    xp = namespace(v)
    z = xp.zeros_like(v[..., 0])
    x, y, w = v[..., 0], v[..., 1], v[..., 2]
    return xp.stack([xp.stack([z, -w, y], -1), xp.stack([w, z, -x], -1), xp.stack([-y, x, z], -1)], -2)


def _norm(x, keepdim: bool = False):
    """The Euclidean norm over the last axis."""
    if is_tensor(x):
        return x.norm(dim=-1, keepdim=keepdim)
    return np.linalg.norm(x, axis=-1, keepdims=keepdim)


def axis_angle_to_matrix(r: Tensor) -> Tensor:
    """Rodrigues' formula. r: (..., 3) axis times angle (radians) -> (..., 3, 3).

    Uses Taylor expansions of sin(t)/t and (1-cos t)/t^2 near t = 0 so gradients stay finite.
    """
    xp = namespace(r)
    theta2 = (r * r).sum(-1)
    small = theta2 < 1e-8
    theta2_safe = xp.where(small, xp.ones_like(theta2), theta2)
    theta = xp.sqrt(theta2_safe)
    a = xp.where(small, 1.0 - theta2 / 6.0, xp.sin(theta) / theta)
    b = xp.where(small, 0.5 - theta2 / 24.0, (1.0 - xp.cos(theta)) / theta2_safe)
    k = _skew(r)
    if is_tensor(r):
        eye = xp.eye(3, dtype=r.dtype, device=r.device).expand(k.shape)
    else:
        eye = np.broadcast_to(np.eye(3, dtype=r.dtype), k.shape)
    return eye + a[..., None, None] * k + b[..., None, None] * (k @ k)


def matrix_to_quaternion(R: Tensor) -> Tensor:  # noqa: N803
    """(..., 3, 3) -> (..., 4) unit quaternion (w, x, y, z), w >= 0 (Shepperd's method)."""
    xp = namespace(R)
    m = R
    t = m[..., 0, 0] + m[..., 1, 1] + m[..., 2, 2]
    cands = xp.stack(
        [
            xp.stack(
                [
                    1 + t,
                    m[..., 2, 1] - m[..., 1, 2],
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 1, 0] - m[..., 0, 1],
                ],
                -1,
            ),
            xp.stack(
                [
                    m[..., 2, 1] - m[..., 1, 2],
                    1 + 2 * m[..., 0, 0] - t,
                    m[..., 0, 1] + m[..., 1, 0],
                    m[..., 0, 2] + m[..., 2, 0],
                ],
                -1,
            ),
            xp.stack(
                [
                    m[..., 0, 2] - m[..., 2, 0],
                    m[..., 0, 1] + m[..., 1, 0],
                    1 + 2 * m[..., 1, 1] - t,
                    m[..., 1, 2] + m[..., 2, 1],
                ],
                -1,
            ),
            xp.stack(
                [
                    m[..., 1, 0] - m[..., 0, 1],
                    m[..., 0, 2] + m[..., 2, 0],
                    m[..., 1, 2] + m[..., 2, 1],
                    1 + 2 * m[..., 2, 2] - t,
                ],
                -1,
            ),
        ],
        -2,
    )  # (..., 4, 4); row i is 4*q_i*q scaled, best conditioned where its diagonal entry is largest
    diag = xp.stack([1 + t, 1 + 2 * m[..., 0, 0] - t, 1 + 2 * m[..., 1, 1] - t, 1 + 2 * m[..., 2, 2] - t], -1)
    idx = diag.argmax(-1)
    if is_tensor(R):
        q = xp.gather(cands, -2, idx[..., None, None].expand(*idx.shape, 1, 4)).squeeze(-2)
    else:
        q = np.take_along_axis(cands, idx[..., None, None], -2)[..., 0, :]
    q = q / _norm(q, keepdim=True)
    return xp.where(q[..., :1] < 0, -q, q)


def quaternion_to_matrix(q: Tensor) -> Tensor:
    """(..., 4) quaternion (w, x, y, z), not necessarily unit -> (..., 3, 3)."""
    xp = namespace(q)
    q = q / _norm(q, keepdim=True)
    w, x, y, z = q[..., 0], q[..., 1], q[..., 2], q[..., 3]
    return xp.stack(
        [
            xp.stack([1 - 2 * (y * y + z * z), 2 * (x * y - w * z), 2 * (x * z + w * y)], -1),
            xp.stack([2 * (x * y + w * z), 1 - 2 * (x * x + z * z), 2 * (y * z - w * x)], -1),
            xp.stack([2 * (x * z - w * y), 2 * (y * z + w * x), 1 - 2 * (x * x + y * y)], -1),
        ],
        -2,
    )


def matrix_to_axis_angle(R: Tensor) -> Tensor:  # noqa: N803
    """(..., 3, 3) -> (..., 3) axis times angle in [0, pi], via the quaternion (stable near 0 and pi)."""
    xp = namespace(R)
    q = matrix_to_quaternion(R)
    vec = q[..., 1:]
    s = _norm(vec)
    angle = 2.0 * xp.arctan2(s, q[..., 0])
    scale = xp.where(s > 1e-8, angle / clamp(s, 1e-12), 2.0 / clamp(q[..., 0], 1e-12))
    return vec * scale[..., None]


def rotation_6d_to_matrix(x: Tensor) -> Tensor:
    """(..., 6) -> (..., 3, 3) by Gram-Schmidt on the two given columns (Zhou et al. 2019); tensors only."""
    import torch

    a1, a2 = x[..., :3], x[..., 3:]
    b1 = torch.nn.functional.normalize(a1, dim=-1)
    b2 = torch.nn.functional.normalize(a2 - (b1 * a2).sum(-1, keepdim=True) * b1, dim=-1)
    b3 = torch.linalg.cross(b1, b2, dim=-1)
    return torch.stack([b1, b2, b3], dim=-1)


def matrix_to_rotation_6d(R: Tensor) -> Tensor:  # noqa: N803
    """(..., 3, 3) -> (..., 6): the first two columns; tensors only."""
    import torch

    return torch.cat([R[..., :, 0], R[..., :, 1]], dim=-1)

"""Free-space bookkeeping for placing objects: upright boxes (any yaw) that may touch but not overlap.

Every placed part and every reserved region (the camera's spot, the space in front of a doorway) is an
upright box: a rotated rectangle in the floor plane times a height interval. Two boxes collide when their
rectangles overlap (separating-axis test) and their height intervals overlap, both by more than ``EPS`` —
so furniture can stand flush against walls and against each other.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cuboidcli.synth.world import rot_z

EPS = 1e-6


@dataclass
class Pose:
    """Placement of an object frame in the world: floor position ``xy`` (2,), height ``z`` and ``yaw``."""

    xy: np.ndarray
    z: float
    yaw: float

    @property
    def rotation(self) -> np.ndarray:
        return rot_z(self.yaw)

    def apply(self, local: np.ndarray) -> np.ndarray:
        """Object-frame points (..., 3) -> world points (..., 3)."""
        return np.asarray(local, float) @ self.rotation.T + np.array([self.xy[0], self.xy[1], self.z])


class Occupancy:
    """The upright boxes placed so far: centres (N, 2), yaws (N,), half-extents (N, 2), z intervals (N, 2)."""

    def __init__(self) -> None:
        self.center = np.zeros((0, 2))
        self.yaw = np.zeros(0)
        self.half = np.zeros((0, 2))
        self.z = np.zeros((0, 2))

    def __len__(self) -> int:
        return len(self.yaw)

    def add(self, center, yaw, half, z) -> None:
        """Add boxes: center (K, 2), yaw (K,), half (K, 2), z (K, 2) (or single boxes without the K axis)."""
        self.center = np.concatenate([self.center, np.reshape(center, (-1, 2))])
        self.yaw = np.concatenate([self.yaw, np.reshape(yaw, -1)])
        self.half = np.concatenate([self.half, np.reshape(half, (-1, 2))])
        self.z = np.concatenate([self.z, np.reshape(z, (-1, 2))])

    def collides(self, center, yaw, half, z) -> bool:
        """Does any of the K candidate boxes (same shapes as :meth:`add`) overlap a placed box?"""
        if len(self) == 0:
            return False
        center, yaw = np.reshape(center, (-1, 2)), np.reshape(yaw, -1)
        half, z = np.reshape(half, (-1, 2)), np.reshape(z, (-1, 2))
        z_overlap = (
            np.minimum(z[:, None, 1], self.z[None, :, 1]) - np.maximum(z[:, None, 0], self.z[None, :, 0])
        ) > EPS  # (K, N)
        if not z_overlap.any():
            return False
        ax_a = _axes(yaw)[:, None]  # (K, 1, 2, 2): two unit axes per box
        ax_b = _axes(self.yaw)[None]  # (1, N, 2, 2)
        d = self.center[None] - center[:, None]  # (K, N, 2)
        separated = np.zeros(z_overlap.shape, bool)
        for axes in (ax_a, ax_b):
            for k in range(2):
                u = axes[..., k, :][..., None, :]  # candidate separating axis, broadcast to (K, N, 1, 2)
                ra = (np.abs((u * ax_a).sum(-1)) * half[:, None]).sum(-1)  # projected half-widths (K, N)
                rb = (np.abs((u * ax_b).sum(-1)) * self.half[None]).sum(-1)
                dist = np.abs((u[..., 0, :] * d).sum(-1))
                separated |= dist >= ra + rb - EPS
        return bool((z_overlap & ~separated).any())


def _axes(yaw: np.ndarray) -> np.ndarray:
    """Unit x and y axes of rectangles with the given yaws: (N,) -> (N, 2, 2), axis index second."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2)


def upright_boxes(pose: Pose, lo: np.ndarray, hi: np.ndarray) -> tuple[np.ndarray, ...]:
    """Object-frame axis-aligned boxes lo, hi (K, 3) -> world upright boxes (center, yaw, half, z)."""
    lo, hi = np.reshape(lo, (-1, 3)), np.reshape(hi, (-1, 3))
    mid = (lo + hi) / 2
    center = pose.apply(mid)[:, :2]
    half = (hi - lo)[:, :2] / 2
    z = np.stack([lo[:, 2], hi[:, 2]], -1) + pose.z
    return center, np.full(len(lo), pose.yaw), half, z

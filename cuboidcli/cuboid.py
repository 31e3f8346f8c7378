"""The one cuboid type used at module boundaries.

A cuboid is (centre, half-sizes, rotation) in OpenCV camera coordinates, metres. The columns of
``rotation`` are the cuboid's local axes: a local point ``p`` maps to ``rotation @ p + center`` and the
box spans ``[-half_size, +half_size]`` along its local axes (the paper's (a_x, a_y, a_z, R, t)).
Batches travel between modules as arrays (numpy, or tensors where torch computes): centres (..., 3),
half-sizes (..., 3), rotations (..., 3, 3).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from itertools import product

import numpy as np

#: Distinct colours (RGB) shared by every output (JSON, overlays, GLB, PLY), in selection order.
PALETTE: tuple[tuple[int, int, int], ...] = (
    (230, 25, 75),
    (60, 180, 75),
    (67, 99, 216),
    (245, 130, 49),
    (145, 30, 180),
    (70, 240, 240),
    (240, 50, 230),
    (188, 246, 12),
    (250, 190, 190),
    (0, 128, 128),
    (154, 99, 36),
    (255, 225, 25),
    (128, 0, 0),
    (170, 255, 195),
    (128, 128, 0),
    (0, 0, 117),
)


def palette_color(i: int) -> tuple[int, int, int]:
    return PALETTE[i % len(PALETTE)]


#: What a cuboid is in the room (Cuboid.kind): the room's shell, or anything else.
KINDS = ("floor", "wall", "ceiling", "object")


@dataclass
class Cuboid:
    """One oriented box. ``center`` (3,), ``half_size`` (3,), ``rotation`` (3, 3), float64 numpy."""

    center: np.ndarray
    half_size: np.ndarray
    rotation: np.ndarray
    inlier_gain: float | None = None
    extras: dict = field(default_factory=dict)
    kind: str = "object"
    """What the box is in the room: ``floor``, ``wall``, ``ceiling`` or ``object`` (:data:`KINDS`)."""

    def __post_init__(self) -> None:
        if self.kind not in KINDS:
            raise ValueError(f"cuboid kind {self.kind!r}: choose {', '.join(KINDS)}")
        self.center = np.asarray(self.center, dtype=np.float64).reshape(3)
        self.half_size = np.asarray(self.half_size, dtype=np.float64).reshape(3)
        self.rotation = np.asarray(self.rotation, dtype=np.float64).reshape(3, 3)

    @property
    def quat_wxyz(self) -> np.ndarray:
        from cuboidcli.geometry.rotations import matrix_to_quaternion

        return matrix_to_quaternion(self.rotation)

    @classmethod
    def from_quat(cls, center, half_size, quat_wxyz, **kw) -> Cuboid:
        return cls(center, half_size, _quat_matrix(quat_wxyz), **kw)

    def corners(self) -> np.ndarray:
        """(8, 3) corners in camera coordinates; corner k has local signs product((-1, 1), repeat=3)[k]."""
        signs = np.array(list(product((-1.0, 1.0), repeat=3)))
        return (signs * self.half_size) @ self.rotation.T + self.center

    def volume(self) -> float:
        return float(8.0 * np.prod(self.half_size))

    def top(self, up: np.ndarray) -> float:
        """The height of the box's highest corner along the unit direction ``up`` (3,)."""
        return float(self.center @ up + np.abs(self.rotation.T @ up) @ self.half_size)

    def parameters_json(self) -> dict:
        """The box's parameters, JSON-safe: centre, half-sizes, rotation, quaternion (wxyz), inlier gain."""
        return {
            "center": [float(v) for v in self.center],
            "half_size": [float(v) for v in self.half_size],
            "rotation": [[float(v) for v in row] for row in self.rotation],
            "quat_wxyz": [float(v) for v in self.quat_wxyz],
            "inlier_gain": None if self.inlier_gain is None else float(self.inlier_gain),
        }

    def name(self, index: int) -> str:
        """The box's name in every scene file (GLB, MJCF, URDF, USD, rerun, HTML): floor_00, wall_01,
        object_05 (``index``: its position in the list)."""
        return f"{self.kind}_{index:02d}"

    def to_json(self, index: int) -> dict:
        d = {"id": index, "kind": self.kind, **self.parameters_json(), "color": list(palette_color(index))}
        d.update(self.extras)
        return d

    @classmethod
    def from_json(cls, d: dict) -> Cuboid:
        known = {"id", "kind", "center", "half_size", "rotation", "quat_wxyz", "inlier_gain", "color"}
        extras = {k: v for k, v in d.items() if k not in known}
        if "rotation" in d:
            rot = np.asarray(d["rotation"], dtype=np.float64)
        elif "quat_wxyz" in d:
            rot = _quat_matrix(d["quat_wxyz"])
        else:
            raise ValueError("cuboid entry has neither 'rotation' nor 'quat_wxyz'")
        kind = d.get("kind", "object")  # results written before kinds existed hold objects only
        if kind not in KINDS:
            raise ValueError(f"cuboid kind {kind!r}: expected one of {', '.join(KINDS)}")
        return cls(d["center"], d["half_size"], rot, d.get("inlier_gain"), extras, kind)


def _quat_matrix(quat_wxyz) -> np.ndarray:
    """The (3, 3) rotation of a unit quaternion (w, x, y, z)."""
    from cuboidcli.geometry.rotations import quaternion_to_matrix

    return quaternion_to_matrix(np.asarray(quat_wxyz, dtype=np.float64))


def stack_cuboids(cuboids: list[Cuboid], dtype=None, device="cpu") -> tuple:
    """List of cuboids -> (centres (M, 3), half-sizes (M, 3), rotations (M, 3, 3)) tensors (float32 unless
    ``dtype`` says otherwise)."""
    import torch

    dtype = torch.float32 if dtype is None else dtype
    if not cuboids:
        return (
            torch.zeros(0, 3, dtype=dtype, device=device),
            torch.zeros(0, 3, dtype=dtype, device=device),
            torch.zeros(0, 3, 3, dtype=dtype, device=device),
        )
    c = torch.as_tensor(np.stack([b.center for b in cuboids]), dtype=dtype, device=device)
    a = torch.as_tensor(np.stack([b.half_size for b in cuboids]), dtype=dtype, device=device)
    R = torch.as_tensor(np.stack([b.rotation for b in cuboids]), dtype=dtype, device=device)
    return c, a, R


def unstack_cuboids(centers, half_sizes, rotations) -> list[Cuboid]:
    c = centers.detach().cpu().double().numpy()
    a = half_sizes.detach().cpu().double().numpy()
    R = rotations.detach().cpu().double().numpy()
    return [Cuboid(c[i], a[i], R[i]) for i in range(c.shape[0])]

"""Synthetic minimal sets: the neural solver's pre-training data (paper appendix "Neural Cuboid Solver")
and the fixed inputs of the ONNX export's parity check (:mod:`cuboidcli.solvers.onnx_export`).

Random boxes are seen by a camera at the origin (OpenCV frame, metres). C points are drawn on the sides
that face the camera, a side being chosen with probability proportional to its area times |cos| of the
viewing angle at its centre, the point uniform on the side. The paper's recipe is exactly this; two
additions make the sets look more like samples from a depth map:

- depth noise along the viewing ray, sigma = noise_at_1m * z^2 (structured-light sensors: ~1.5 mm at 1 m),
- a share of sets with one outlier point pushed off the surface (minimal sets drawn from a real scene
  often straddle two objects). Outliers are flagged in ``inlier`` so the loss can ignore them.

Rotations are uniform on SO(3) (the paper drew an axis from the positive octant and an angle in
[-pi, pi], which is not uniform). Everything is drawn from the caller's ``torch.Generator`` on the CPU,
so a seed reproduces a batch exactly.
"""

from __future__ import annotations

from dataclasses import asdict, dataclass

import torch
from torch import Tensor

from cuboidcli.geometry.kernels import SIDE_AXIS, SIDE_SIGN
from cuboidcli.geometry.rotations import quaternion_to_matrix


@dataclass(frozen=True)
class SyntheticConfig:
    """Distribution of the synthetic boxes and minimal sets (indoor values of the paper)."""

    points: int = 6
    """C: points per minimal set."""
    half_size_min: float = 0.01
    """Smallest half-size of a box, m (paper: a ~ U(0.01, 2))."""
    half_size_max: float = 2.0
    """Largest half-size of a box, m."""
    center_xy: float = 5.0
    """Box centre x and y ~ U(-center_xy, center_xy), m."""
    center_z_min: float = 0.5
    """Box centre z ~ U(center_z_min, center_z_max), m."""
    center_z_max: float = 10.0
    min_depth: float = 0.1
    """Sets with a point closer than this to the camera plane (z, m) are redrawn: a depth camera sees
    nothing behind it."""
    noise_at_1m: float = 0.0015
    """Std of the depth noise at 1 m, m; it grows with depth squared. 0 = points exactly on the surface."""
    outlier_rate: float = 0.15
    """Fraction of sets in which one point is moved off the box."""
    outlier_min: float = 0.1
    """An outlier is moved by a distance ~ U(outlier_min, outlier_max) in a random direction, m."""
    outlier_max: float = 1.0

    def to_dict(self) -> dict:
        return asdict(self)

    def clean(self) -> SyntheticConfig:
        """The paper's distribution: no noise, no outliers."""
        return SyntheticConfig(**{**asdict(self), "noise_at_1m": 0.0, "outlier_rate": 0.0})


@dataclass
class SyntheticBatch:
    """``points`` (B, C, 3) m; ``inlier`` (B, C) bool; the true boxes ``centers`` (B, 3), ``half_sizes``
    (B, 3), ``rotations`` (B, 3, 3); ``sides`` (B, C) index of the side each point was drawn on."""

    points: Tensor
    inlier: Tensor
    centers: Tensor
    half_sizes: Tensor
    rotations: Tensor
    sides: Tensor


def random_rotations(n: int, gen: torch.Generator) -> Tensor:
    """(n, 3, 3) rotations uniform on SO(3): normalised Gaussian quaternions."""
    return quaternion_to_matrix(torch.randn(n, 4, generator=gen))


def random_boxes(n: int, cfg: SyntheticConfig, gen: torch.Generator) -> tuple[Tensor, Tensor, Tensor]:
    """(centers (n, 3), half_sizes (n, 3), rotations (n, 3, 3)) drawn from the configured ranges."""
    u = torch.rand(n, 6, generator=gen)
    half = cfg.half_size_min + (cfg.half_size_max - cfg.half_size_min) * u[:, :3]
    xy = (2.0 * u[:, 3:5] - 1.0) * cfg.center_xy
    z = cfg.center_z_min + (cfg.center_z_max - cfg.center_z_min) * u[:, 5:]
    return torch.cat([xy, z], 1), half, random_rotations(n, gen)


def side_weights(centers: Tensor, half_sizes: Tensor, rotations: Tensor) -> Tensor:
    """Sampling weight of each side (B, 6), order (+x, -x, +y, -y, +z, -z): area * cos(viewing angle).

    A side faces the camera (origin) when the camera lies on the outer side of its plane, i.e. when its
    centre p and outward normal n satisfy p . n < 0; then cos = -p . n / |p|. Other sides weigh 0. A box
    is convex, so a facing side is not hidden by the box itself. All weights are 0 if the camera is inside.
    """
    weights = []
    for axis, sign in zip(SIDE_AXIS, SIDE_SIGN, strict=True):
        normal = sign * rotations[:, :, axis]
        centre = centers + half_sizes[:, axis : axis + 1] * normal
        cos = -(centre * normal).sum(-1) / centre.norm(dim=-1).clamp_min(1e-9)
        others = [k for k in range(3) if k != axis]
        area = 4.0 * half_sizes[:, others[0]] * half_sizes[:, others[1]]
        weights.append(area * cos.clamp_min(0.0))
    return torch.stack(weights, -1)


def _points_on_sides(half_sizes: Tensor, sides: Tensor, gen: torch.Generator) -> Tensor:
    """Uniform points in the local frame on the given sides: half_sizes (B, 3), sides (B, C) -> (B, C, 3)."""
    axis = torch.tensor(SIDE_AXIS)[sides]
    sign = torch.tensor(SIDE_SIGN)[sides]
    a = half_sizes[:, None, :].expand(*sides.shape, 3)
    local = (2.0 * torch.rand(*sides.shape, 3, generator=gen) - 1.0) * a
    on_plane = torch.nn.functional.one_hot(axis, 3).bool()
    return torch.where(on_plane, sign[..., None] * a, local)


def _draw(n: int, cfg: SyntheticConfig, gen: torch.Generator) -> SyntheticBatch:
    """One round of noise-free sets; some may violate ``min_depth`` or have no visible side."""
    centers, half, rot = random_boxes(n, cfg, gen)
    weights = side_weights(centers, half, rot)
    seen = weights.sum(-1) > 0
    weights = torch.where(seen[:, None], weights, torch.ones_like(weights))  # dropped below
    sides = torch.multinomial(weights, cfg.points, replacement=True, generator=gen)
    local = _points_on_sides(half, sides, gen)
    points = torch.einsum("bij,bcj->bci", rot, local) + centers[:, None, :]
    keep = seen & (points[..., 2] >= cfg.min_depth).all(-1)
    inlier = torch.ones(points.shape[:2], dtype=torch.bool)
    return SyntheticBatch(points[keep], inlier[keep], centers[keep], half[keep], rot[keep], sides[keep])


def _add_depth_noise(points: Tensor, noise_at_1m: float, gen: torch.Generator) -> Tensor:
    """Move each point along its viewing ray by N(0, (noise_at_1m * z^2)^2): the depth changes, not x/z."""
    z = points[..., 2:]
    dz = torch.randn(z.shape, generator=gen) * noise_at_1m * z.square()
    return points * (1.0 + dz / z)


def _add_outliers(batch: SyntheticBatch, cfg: SyntheticConfig, gen: torch.Generator) -> None:
    """Replace one point of a random ``outlier_rate`` share of the sets by a point off the box, in place."""
    b, c, _ = batch.points.shape
    hit = torch.rand(b, generator=gen) < cfg.outlier_rate
    which = torch.randint(c, (b,), generator=gen)
    direction = torch.nn.functional.normalize(torch.randn(b, 3, generator=gen), dim=-1)
    dist = cfg.outlier_min + (cfg.outlier_max - cfg.outlier_min) * torch.rand(b, 1, generator=gen)
    rows = torch.arange(b)
    moved = batch.points[rows, which] + direction * dist
    moved[:, 2] = moved[:, 2].clamp_min(cfg.min_depth)
    batch.points[rows[hit], which[hit]] = moved[hit]
    batch.inlier[rows[hit], which[hit]] = False


def sample_batch(n: int, cfg: SyntheticConfig, gen: torch.Generator) -> SyntheticBatch:
    """``n`` minimal sets of ``cfg.points`` points, float32 on the CPU, reproducible from ``gen``."""
    parts, have = [], 0
    while have < n:
        # A few per cent of the draws are rejected (camera inside, points behind the camera); draw extra.
        part = _draw(max(64, int(1.4 * (n - have))), cfg, gen)
        parts.append(part)
        have += part.points.shape[0]
    fields = ("points", "inlier", "centers", "half_sizes", "rotations", "sides")
    batch = SyntheticBatch(*(torch.cat([getattr(p, f) for p in parts])[:n] for f in fields))
    if cfg.noise_at_1m > 0:
        batch.points = _add_depth_noise(batch.points, cfg.noise_at_1m, gen)
    if cfg.outlier_rate > 0:
        _add_outliers(batch, cfg, gen)
    return batch


def seeded_batch(n: int, cfg: SyntheticConfig, seed: int) -> SyntheticBatch:
    """A batch determined by ``seed`` alone (fixed validation sets, per-iteration training batches)."""
    return sample_batch(n, cfg, torch.Generator().manual_seed(seed))

"""Which cuboid explains each point: inlier of cuboid k, occluded by the cuboids, or none."""

from __future__ import annotations

import numpy as np

from cuboidcli.cuboid import Cuboid

NONE = -1
OCCLUDED = -2


def assign_points(
    points: np.ndarray,
    cuboids: list[Cuboid],
    tau_sq_m2: float = 0.004,
    beta: float = 5.0,
    tau_c_sq_m2: float | None = None,
    occlusion_aware: bool = True,
) -> np.ndarray:
    """Labels (N,) int32 for points (N, 3) in metres.

    -2 where f_OAI(y, M) < 0 (the point is hidden behind a cuboid side it does not lie on), otherwise the
    index of the cuboid with the highest inlier value if that value is >= 0.5 (d^2 <= tau), else -1.
    """
    from cuboidcli.geometry.fused import cuboid_values

    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    labels = np.full(points.shape[0], NONE, dtype=np.int32)
    if not cuboids or points.shape[0] == 0:
        return labels
    tau_c = 2.0 * tau_sq_m2 if tau_c_sq_m2 is None else tau_c_sq_m2
    c = np.stack([b.center for b in cuboids])
    a = np.stack([b.half_size for b in cuboids])
    R = np.stack([b.rotation for b in cuboids])
    vals = cuboid_values(points, c, a, R, tau_sq_m2, beta, tau_c, occlusion_aware)  # (M, N)
    lo = vals.min(0)
    best = vals.argmax(0)
    hi = vals.max(0)
    labels[hi >= 0.5] = best[hi >= 0.5]
    labels[lo < 0] = OCCLUDED
    return labels

"""Which cuboid explains each point: inlier of cuboid k, occluded by the cuboids, or none."""

from __future__ import annotations

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.backend import ScoringBackend, backend_for
from cuboidcli.fitting.scoring import ScoreParams
from cuboidcli.geometry.arrays import device_of, float64, like, numpy64
from cuboidcli.geometry.inlier import INLIER_CUT

NONE = -1
OCCLUDED = -2


def assign_points(
    points,
    cuboids: list[Cuboid],
    sp: ScoreParams | None = None,
    backend: ScoringBackend | None = None,
) -> np.ndarray:
    """Labels (N,) int32 for points (N, 3) in metres (an array, or a tensor on any device).

    -2 where f_OAI(y, M) < 0 (the point is hidden behind a cuboid side it does not lie on), otherwise the
    index of the cuboid with the highest inlier value if that value is >= ``INLIER_CUT`` (0.5: d^2 <= tau),
    else -1. ``sp``: the inlier function's parameters (None: the defaults, the paper's).
    The values come from ``backend`` (None: the default backend of the points' device, numba on the CPU).
    """
    pts = float64(points).reshape(-1, 3)
    labels = np.full(pts.shape[0], NONE, dtype=np.int32)
    if not cuboids or pts.shape[0] == 0:
        return labels
    backend = backend or backend_for("auto", device_of(pts))
    sp = sp or ScoreParams()
    boxes = (
        like(np.stack([getattr(b, name) for b in cuboids]).astype(np.float64), pts)
        for name in ("center", "half_size", "rotation")
    )
    vals = numpy64(backend.values(pts, *boxes, sp))  # (M, N)
    lo = vals.min(0)
    best = vals.argmax(0)
    hi = vals.max(0)
    inlier = hi >= INLIER_CUT
    labels[inlier] = best[inlier]
    labels[lo < 0] = OCCLUDED
    return labels

"""Recall of the OA distances: AUC@X (paper Sec. 4 "Metrics") and the recall curve, with statistics that
pool over frames by adding up.

AUC@X is the area under the recall curve of the OA distances up to X, divided by X (:func:`auc`, the direct
definition); :class:`AucStats` holds the sums that give the same value and add over frames, so that a run's
AUC is pooled over all points of all frames (as the paper) and not averaged over frames.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

#: Default AUC upper bounds (cm): the paper's indoor values; outdoors it uses 50 and 10.
AUC_CM = (20.0, 5.0)

#: Distances (cm) at which the recall curve is sampled (the report plots it; AUC@X is its area up to X).
RECALL_CURVE_CM = tuple(float(c) for c in range(0, 51))


def recall_counts(distances_m: np.ndarray) -> list[int]:
    """Points with an OA distance at most each distance of :data:`RECALL_CURVE_CM` (inf never is)."""
    d = np.sort(np.asarray(distances_m, dtype=np.float64).ravel())
    return [int(np.searchsorted(d, cm / 100.0, side="right")) for cm in RECALL_CURVE_CM]


def pooled_recall_pct(frames: list) -> list[float] | None:
    """The recall curve (%) pooled over frames (their points together) at :data:`RECALL_CURVE_CM`; None
    when no frame has one."""
    have = [m for m in frames if m.recall_counts is not None]
    n = sum(m.n_points for m in have)
    if not n:
        return None
    return [100.0 * sum(m.recall_counts[i] for m in have) / n for i in range(len(RECALL_CURVE_CM))]


def auc(distances_m: np.ndarray, threshold_m: float) -> float:
    """AUC@X of a list of distances, in [0, 1]: the reference, direct definition.

    The recall curve has a point (d_i, i / N) for the i-th smallest distance; it is cut at X = threshold_m
    (points with d <= X, then (X, k / N) with k of them), integrated by the trapezoid rule and divided by X.
    N counts every distance, infinite ones included.
    """
    d = np.sort(np.asarray(distances_m, dtype=np.float64).ravel())
    n = d.size
    k = int(np.searchsorted(d, threshold_m, side="right"))
    if n == 0 or k == 0:
        return 0.0
    x = np.append(d[:k], threshold_m)
    y = np.append(np.arange(1, k + 1) / n, k / n)
    return float(np.trapezoid(y, x) / threshold_m)


@dataclass
class AucStats:
    """Sufficient statistics of the trapezoid AUC of :func:`auc`, additive over frames (pooling).

    For the sorted distances d_1 <= ... <= d_k <= X among N, the trapezoid area is
    sum_i (X - d_i) / N + (d_k - d_1) / (2 N): the exact step-function integral plus half a step per segment.
    """

    threshold_m: float
    n: int = 0
    excess_sum: float = 0.0
    d_first: float = math.inf
    d_last: float = -math.inf

    @classmethod
    def of(cls, distances_m: np.ndarray, threshold_m: float) -> AucStats:
        d = np.asarray(distances_m, dtype=np.float64).ravel()
        kept = d[d <= threshold_m]
        s = cls(threshold_m, n=int(d.size), excess_sum=float((threshold_m - kept).sum()))
        if kept.size:
            s.d_first, s.d_last = float(kept.min()), float(kept.max())
        return s

    def merge(self, other: AucStats) -> AucStats:
        if other.threshold_m != self.threshold_m:
            raise ValueError("cannot pool AUC statistics of different thresholds")
        return AucStats(
            self.threshold_m,
            self.n + other.n,
            self.excess_sum + other.excess_sum,
            min(self.d_first, other.d_first),
            max(self.d_last, other.d_last),
        )

    @property
    def value(self) -> float:
        """AUC in [0, 1]."""
        if self.n == 0 or self.d_last < self.d_first:
            return 0.0
        area = self.excess_sum / self.n + (self.d_last - self.d_first) / (2.0 * self.n)
        return area / self.threshold_m

    def to_dict(self) -> dict:
        return {
            "threshold_m": self.threshold_m,
            "n": self.n,
            "excess_sum": self.excess_sum,
            "d_first": self.d_first,
            "d_last": self.d_last,
        }


def auc_key(threshold_cm: float) -> str:
    return f"auc{threshold_cm:g}cm_pct"

"""The paper's metrics (Sec. 4 "Metrics", Table 1) per frame and aggregated over frames.

Per frame, on all valid full-resolution depth points:

- ``cuboids``: |M|.
- ``coverage``: fraction of image pixels covered by a projected cuboid (:mod:`.coverage`).
- ``oa_all_m``: mean OA-L2 distance (:mod:`.oa`) over the frame's valid points.
- ``oa_covered_m``: the same over valid points whose pixel is covered; undefined (NaN) with no such point.
- AUC@X: area under the recall curve of the OA distances up to X, divided by X (see :func:`auc`).

Aggregated over the frames of a run (as the paper): |M|, coverage and time are means over frames; OA "all"
is the mean of the per-frame means; OA "covered" the mean over frames with covered points; AUC is POOLED
over all points of all frames, not averaged over frames.

Frames with no cuboid: every OA distance is infinite (there is no surface). Their points count in the
pooled AUC with zero recall, and the frame is excluded from both OA means (reported instead as
``frames_without_cuboids``) so that a single empty frame does not make the mean infinite. The paper's
method always returned at least one cuboid, so its numbers are unaffected by this choice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.coverage import coverage_mask
from cuboidcli.evaluation.iou import greedy_matches, iou_matrix
from cuboidcli.evaluation.oa import oa_distances

#: Default AUC upper bounds (cm): the paper's indoor values; outdoors it uses 50 and 10.
AUC_CM = (20.0, 5.0)
#: IoU thresholds of the ground-truth cuboid recall/precision.
IOU_THRESHOLDS = (0.25, 0.5)


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


@dataclass
class FrameMetrics:
    """Metrics of one frame. Distances in metres, coverage as a fraction, time in seconds."""

    name: str
    cuboids: int
    coverage: float
    oa_all_m: float
    oa_covered_m: float
    n_points: int
    n_covered_points: int
    auc: dict[float, AucStats]
    """Keyed by the threshold in cm."""
    time_s: float | None = None
    gt_matches: dict[float, tuple[int, int, int]] | None = None
    """Keyed by IoU threshold: (matched, ground-truth cuboids, predicted cuboids); None without GT."""
    extras: dict = field(default_factory=dict)

    def row(self) -> dict:
        """Flat row in reporting units (cm, %), for frames.csv and metrics.json."""
        r = {
            "frame": self.name,
            "time_s": self.time_s,
            "cuboids": self.cuboids,
            "coverage_pct": 100.0 * self.coverage,
            "oa_covered_cm": 100.0 * self.oa_covered_m,
            "oa_all_cm": 100.0 * self.oa_all_m,
        }
        for cm, stats in self.auc.items():
            r[auc_key(cm)] = 100.0 * stats.value
        for thr, (tp, n_gt, n_pred) in (self.gt_matches or {}).items():
            r[f"recall_iou{thr:g}_pct"] = 100.0 * tp / n_gt if n_gt else math.nan
            r[f"precision_iou{thr:g}_pct"] = 100.0 * tp / n_pred if n_pred else math.nan
        r["points"] = self.n_points
        r["covered_points"] = self.n_covered_points
        r.update(self.extras)
        return r


def auc_key(threshold_cm: float) -> str:
    return f"auc{threshold_cm:g}cm_pct"


def gt_match_counts(pred: list[Cuboid], gt: list[Cuboid], thresholds=IOU_THRESHOLDS) -> dict:
    """(matched, |GT|, |pred|) per IoU threshold, with a greedy one-to-one matching."""
    ious = iou_matrix(pred, gt)
    return {float(t): (len(greedy_matches(ious, t)), len(gt), len(pred)) for t in thresholds}


def frame_metrics(
    name: str,
    depth_m: np.ndarray,
    camera: Camera,
    cuboids: list[Cuboid],
    auc_cm=AUC_CM,
    gt: list[Cuboid] | None = None,
    time_s: float | None = None,
) -> FrameMetrics:
    """All metrics of one frame: depth_m (H, W) metres (0 = missing), the frame's camera and cuboids."""
    valid = valid_depth(depth_m)
    points = camera.backproject(np.where(valid, depth_m, 0.0))[valid]  # (N, 3)
    dist = oa_distances(points, cuboids)  # (N,), inf without cuboids
    covered = coverage_mask(camera, cuboids)
    cov_pts = covered[valid]
    n_cov = int(cov_pts.sum())
    finite = bool(cuboids) and dist.size > 0
    return FrameMetrics(
        name=name,
        cuboids=len(cuboids),
        coverage=float(covered.mean()),
        oa_all_m=float(dist.mean()) if finite else math.nan,
        oa_covered_m=float(dist[cov_pts].mean()) if finite and n_cov else math.nan,
        n_points=int(dist.size),
        n_covered_points=n_cov,
        auc={float(cm): AucStats.of(dist, cm / 100.0) for cm in auc_cm},
        time_s=time_s,
        gt_matches=None if gt is None else gt_match_counts(cuboids, gt),
    )


def _nanmean(values) -> float:
    v = np.array([x for x in values if x is not None], dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else math.nan


def aggregate(frames: list[FrameMetrics]) -> dict:
    """Aggregates of one run in reporting units, keys in the paper's column order (see module docstring)."""
    if not frames:
        return {"frames": 0}
    out = {
        "time_s": _nanmean(f.time_s for f in frames),
        "cuboids": float(np.mean([f.cuboids for f in frames])),
        "coverage_pct": 100.0 * float(np.mean([f.coverage for f in frames])),
        "oa_covered_cm": 100.0 * _nanmean(f.oa_covered_m for f in frames),
        "oa_all_cm": 100.0 * _nanmean(f.oa_all_m for f in frames),
    }
    for cm in frames[0].auc:
        pooled = frames[0].auc[cm]
        for f in frames[1:]:
            pooled = pooled.merge(f.auc[cm])
        out[auc_key(cm)] = 100.0 * pooled.value
    with_gt = [f for f in frames if f.gt_matches is not None]
    if with_gt:
        for thr in with_gt[0].gt_matches:
            tp = sum(f.gt_matches[thr][0] for f in with_gt)
            n_gt = sum(f.gt_matches[thr][1] for f in with_gt)
            n_pred = sum(f.gt_matches[thr][2] for f in with_gt)
            out[f"recall_iou{thr:g}_pct"] = 100.0 * tp / n_gt if n_gt else math.nan
            out[f"precision_iou{thr:g}_pct"] = 100.0 * tp / n_pred if n_pred else math.nan
    out["frames"] = len(frames)
    out["frames_without_cuboids"] = sum(1 for f in frames if f.cuboids == 0)
    out["frames_with_gt"] = len(with_gt)
    return out


def mean_std(runs: list[dict]) -> dict[str, tuple[float, float]]:
    """Mean and population std (ddof 0) of each aggregate over runs, like the paper's tables."""
    out = {}
    for key in runs[0]:
        vals = np.array([r.get(key, math.nan) for r in runs], dtype=np.float64)
        fin = vals[np.isfinite(vals)]
        out[key] = (float(fin.mean()), float(fin.std())) if fin.size else (math.nan, math.nan)
    return out

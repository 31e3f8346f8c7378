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

Further measurements (computed by ``cuboids evaluate``; optional arguments of :func:`frame_metrics`):

- **Parsimony curve**: AUC@X and coverage of the first k cuboids in selection order (the order of the
  list), k = 1..K (K = ``config.max_cuboids``, or more if a frame has more cuboids). A frame with fewer than
  k cuboids uses all of them. AUC is pooled over all points of all frames and coverage averaged over
  frames, exactly like the plain values, which the curve reaches at k = K. The per-cuboid OA terms are
  computed once per frame (:func:`.oa.oa_sq_prefix_distances`) and the coverage masks once per cuboid.
- **Object recall / precision** where a per-pixel instance image exists (synthetic data): every valid
  full-resolution point is assigned to a cuboid with the estimator's own rule
  (:func:`cuboidcli.fitting.assign.assign_points`, the config's tau, beta, tau_c and OAI setting). A
  ground-truth object (nonzero instance id: walls, floor, ceiling and clutter too) with at least 1 % of the
  frame's valid points is *eligible*; it is *explained* by a cuboid that holds >= 50 % of the object's
  valid points while >= 50 % of the cuboid's assigned points lie on the object. Recall = explained /
  eligible objects; precision = cuboids that explain an eligible object / predicted cuboids; both pooled
  over frames.
- **Shape** (``shape=True``, :mod:`.shape`): per cuboid the angle of its axes to the up vector and to the
  room's Manhattan axes and the support of its visible faces by its inliers (the same assignment); per
  frame the gravity error where the gravity is known. Pooled over the cuboids (medians, support mean)
  and frames (gravity error) of a run by :func:`shape_summary` and :func:`gravity_summary`. With ground
  truth also ``box_recall_iou25_pct`` / ``box_precision_iou25_pct`` (the IoU 0.25 matching, renamed).

Frames with no cuboid (counted in ``frames_without_cuboids``): there is no surface, so every point counts
with zero recall, in the pooled AUC (its distance is infinite there) and in the object and ground-truth
recalls. The frame is NOT dropped from the OA "all" mean, which would reward a method for giving up on hard
frames: each point's OA distance is taken as its distance to the camera centre,
finite and at least as large as the point's depth. Its coverage is 0, so the OA "covered" mean skips it
like any frame without covered points (the paper's rule). The paper's method always returned at least one
cuboid, so its numbers are unaffected by this choice.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import NamedTuple

import numpy as np

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.coverage import fill_convex, projected_hull
from cuboidcli.evaluation.iou import greedy_matches, iou_matrix
from cuboidcli.evaluation.oa import oa_distances, oa_sq_prefix_distances
from cuboidcli.evaluation.shape import GRAVITY_GOOD_DEG, SOURCES, Reference, ShapeMetrics, shape_metrics
from cuboidcli.fitting.config import FitConfig
from cuboidcli.geometry.gravity import Gravity

#: Default AUC upper bounds (cm): the paper's indoor values; outdoors it uses 50 and 10.
AUC_CM = (20.0, 5.0)
#: IoU thresholds of the ground-truth cuboid recall/precision.
IOU_THRESHOLDS = (0.25, 0.5)
#: The IoU threshold of ``box_recall_iou25_pct`` / ``box_precision_iou25_pct``.
BOX_IOU = 0.25
#: An object is eligible for object recall with at least this percentage of the frame's valid points.
OBJECT_MIN_PCT = 1
#: A cuboid explains an object when it holds at least this percentage of the object's points and at least
#: this percentage of the cuboid's assigned points lie on the object.
OBJECT_EXPLAIN_PCT = 50


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


class ObjectCounts(NamedTuple):
    """Object recall / precision counts of one frame (pooled by summing)."""

    explained: int
    """Eligible objects explained by a cuboid."""
    eligible: int
    """Objects with >= OBJECT_MIN_PCT % of the frame's valid points."""
    explaining: int
    """Predicted cuboids that explain an eligible object."""
    predicted: int
    """Predicted cuboids."""


def object_counts(labels: np.ndarray, instance_ids: np.ndarray, n_cuboids: int) -> ObjectCounts:
    """Object recall / precision counts from a per-point assignment.

    ``labels`` (N,) per valid point: the cuboid index (>= 0), -1 (none) or -2 (occluded), as
    :func:`cuboidcli.fitting.assign.assign_points` returns; ``instance_ids`` (N,) the ground-truth object id
    of each point (0 = no object). N (all valid points) is the base of the eligibility threshold.
    """
    labels = np.asarray(labels).ravel()
    ids = np.asarray(instance_ids).ravel().astype(np.int64)
    n = ids.size
    if labels.size != n:
        raise ValueError(f"{labels.size} labels for {n} instance ids")
    if n == 0:
        return ObjectCounts(0, 0, 0, n_cuboids)
    present = np.flatnonzero(np.bincount(ids))  # object ids with points, ascending (0 first if present)
    index = np.zeros(int(ids.max()) + 1, dtype=np.int64)
    index[present] = np.arange(present.size)
    obj = index[ids]  # (N,) dense object index
    sizes = np.bincount(obj, minlength=present.size)
    eligible = (present != 0) & (100 * sizes >= OBJECT_MIN_PCT * n)
    n_eligible = int(eligible.sum())
    if n_cuboids == 0 or n_eligible == 0:
        return ObjectCounts(0, n_eligible, 0, n_cuboids)
    on = labels >= 0
    joint = np.bincount(
        obj[on] * n_cuboids + labels[on].astype(np.int64), minlength=present.size * n_cuboids
    ).reshape(present.size, n_cuboids)  # joint[o, h]: points of object o assigned to cuboid h
    assigned = joint.sum(axis=0)  # points assigned to each cuboid (on any object or none)
    explains = (
        eligible[:, None]
        & (joint > 0)
        & (100 * joint >= OBJECT_EXPLAIN_PCT * sizes[:, None])
        & (100 * joint >= OBJECT_EXPLAIN_PCT * assigned[None, :])
    )
    return ObjectCounts(
        explained=int(explains.any(axis=1).sum()),
        eligible=n_eligible,
        explaining=int(explains.any(axis=0).sum()),
        predicted=n_cuboids,
    )


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
    objects: ObjectCounts | None = None
    """Object recall / precision counts; None without an instance image."""
    prefix_coverage: list[float] | None = None
    """Parsimony curve: coverage (fraction) of the first k cuboids, k = 1..K; None when not computed."""
    prefix_auc: dict[float, list[AucStats]] | None = None
    """Parsimony curve: AUC statistics of the first k cuboids, k = 1..K, keyed by the threshold in cm."""
    shape: ShapeMetrics | None = None
    """Axis angles, support and the gravity error (:mod:`.shape`); None when not computed."""
    extras: dict = field(default_factory=dict)
    recall_counts: list[int] | None = None
    """Recall curve: the number of points within each distance of :data:`RECALL_CURVE_CM` of the
    abstraction (of ``n_points``); additive over frames like the AUC statistics."""

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
        if self.objects is not None:
            r.update(object_rates(*self.objects))
            r["objects_eligible"] = self.objects.eligible
        r["points"] = self.n_points
        r["covered_points"] = self.n_covered_points
        if self.gt_matches is not None and BOX_IOU in self.gt_matches:
            r.update(box_rates(*self.gt_matches[BOX_IOU]))
        if self.shape is not None:
            r["gravity_ref"] = self.shape.reference
            r.update(shape_summary([self.shape]))
            if self.shape.gravity_error_of:
                r["gravity_error_deg"] = self.shape.gravity_error_deg
                r["gravity_error_of"] = self.shape.gravity_error_of
        r.update(self.extras)
        return r

    def cuboid_rows(self) -> list[dict]:
        """One row per predicted cuboid (selection order) with its shape measurements; [] without them."""
        s = self.shape
        if s is None:
            return []
        support = s.support
        return [
            {
                "frame": self.name,
                "cuboid": k,
                "axis_angle_gravity_deg": float(s.angle_gravity_deg[k]),
                "axis_angle_manhattan_deg": float(s.angle_manhattan_deg[k]),
                "slab": bool(s.slab[k]),
                "room_slab": bool(s.room[k]),
                "visible_px": int(s.visible_px[k]),
                "supported_px": int(s.supported_px[k]),
                "support_pct": 100.0 * float(support[k]),
                "gravity_ref": s.reference,
            }
            for k in range(len(s.slab))
        ]


def auc_key(threshold_cm: float) -> str:
    return f"auc{threshold_cm:g}cm_pct"


def object_rates(explained: int, eligible: int, explaining: int, predicted: int) -> dict:
    """Object recall and precision in % (NaN with a zero denominator)."""
    return {
        "object_recall_pct": 100.0 * explained / eligible if eligible else math.nan,
        "object_precision_pct": 100.0 * explaining / predicted if predicted else math.nan,
    }


def box_rates(matched: int, n_gt: int, n_pred: int) -> dict:
    """Ground-truth box recall and precision at IoU :data:`BOX_IOU` in % (NaN with a zero denominator)."""
    return {
        "box_recall_iou25_pct": 100.0 * matched / n_gt if n_gt else math.nan,
        "box_precision_iou25_pct": 100.0 * matched / n_pred if n_pred else math.nan,
    }


def _median(values) -> float:
    v = np.asarray(values, dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(np.median(v)) if v.size else math.nan


def shape_summary(shapes: list[ShapeMetrics]) -> dict:
    """Axis angles, slab alignment and support pooled over the cuboids of ``shapes`` (frames), in reporting
    units: medians over all cuboids with a defined value (NaN when none)."""
    ang_g = np.concatenate([s.angle_gravity_deg for s in shapes])
    ang_m = np.concatenate([s.angle_manhattan_deg for s in shapes])
    support = np.concatenate([s.support for s in shapes])
    support = support[np.isfinite(support)]
    slabs = sum(s.slabs_measured for s in shapes)
    room = sum(s.room_slabs_measured for s in shapes)
    return {
        "axis_angle_gravity_median_deg": _median(ang_g),
        "axis_angle_manhattan_median_deg": _median(ang_m),
        "slabs": slabs,
        "slabs_within_3deg_pct": 100.0 * sum(s.slabs_aligned for s in shapes) / slabs if slabs else math.nan,
        "room_slabs": room,
        "room_slabs_within_3deg_pct": (
            100.0 * sum(s.room_slabs_aligned for s in shapes) / room if room else math.nan
        ),
        "support_median_pct": 100.0 * float(np.median(support)) if support.size else math.nan,
        "support_mean_pct": 100.0 * float(support.mean()) if support.size else math.nan,
    }


def gravity_summary(shapes: list[ShapeMetrics]) -> dict:
    """The gravity error over the frames with a known gravity (none: {}). A frame without a reliable
    estimate counts in the denominator of the share within :data:`GRAVITY_GOOD_DEG` but not in the median
    and maximum; it is counted in ``gravity_estimates_missing``."""
    known = [s for s in shapes if s.gravity_error_of]
    if not known:
        return {}
    err = np.array([s.gravity_error_deg for s in known], dtype=np.float64)
    fin = err[np.isfinite(err)]
    return {
        "gravity_error_median_deg": float(np.median(fin)) if fin.size else math.nan,
        "gravity_error_max_deg": float(fin.max()) if fin.size else math.nan,
        "gravity_within_2deg_pct": 100.0 * float((fin <= GRAVITY_GOOD_DEG).sum()) / len(known),
        "frames_with_known_gravity": len(known),
        "gravity_estimates_missing": int(len(known) - fin.size),
    }


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
    parsimony_k: int | None = None,
    instances: np.ndarray | None = None,
    config: FitConfig | None = None,
    shape: bool = False,
    fit_gravity: Gravity | None = None,
    known_gravity: Reference | None = None,
) -> FrameMetrics:
    """All metrics of one frame: depth_m (H, W) metres (0 = missing), the frame's camera and cuboids.

    ``parsimony_k``: also compute the parsimony curve for k = 1..max(parsimony_k, len(cuboids)).
    ``instances`` (H, W) integer object ids (0 = none): also count object recall / precision, with the
    point-to-cuboid assignment of ``config`` (tau, beta, tau_c, occlusion_aware; default FitConfig()).
    ``shape``: also measure axis angles, support and the gravity error (:func:`.shape.shape_metrics`)
    against ``fit_gravity`` (the gravity the fit used) or ``known_gravity`` (the frame's true reference),
    else a gravity estimated from the depth map with ``config``'s grid step and seed; the support uses the
    same assignment and tolerates observed points up to sqrt(tau) in front of a face.
    """
    valid = valid_depth(depth_m)
    points = camera.backproject(np.where(valid, depth_m, 0.0))[valid]  # (N, 3)
    prefix_dist = None
    if parsimony_k is not None and cuboids:
        prefix_dist = oa_sq_prefix_distances(points, cuboids)  # (N, M) m^2, column k: first k + 1 cuboids
        np.sqrt(prefix_dist, out=prefix_dist)
        dist = prefix_dist[:, -1]  # equal to oa_distances(points, cuboids)
    else:
        dist = oa_distances(points, cuboids)  # (N,), inf without cuboids
    masks = [fill_convex(projected_hull(c, camera), camera.width, camera.height) for c in cuboids]
    covered = np.zeros((camera.height, camera.width), dtype=bool)
    prefix_cov = []
    for mask in masks:  # cumulative union, in selection order
        covered |= mask
        prefix_cov.append(float(covered.mean()))
    cov_pts = covered[valid]
    n_cov = int(cov_pts.sum())
    auc_stats = {float(cm): AucStats.of(dist, cm / 100.0) for cm in auc_cm}
    # OA means: without a cuboid, a point is as far from the abstraction as from the camera (docstring)
    oa = dist if cuboids else np.linalg.norm(points, axis=1)
    m = FrameMetrics(
        name=name,
        cuboids=len(cuboids),
        coverage=float(covered.mean()),
        oa_all_m=float(oa.mean()) if oa.size else math.nan,
        oa_covered_m=float(oa[cov_pts].mean()) if n_cov else math.nan,
        n_points=int(dist.size),
        n_covered_points=n_cov,
        auc=auc_stats,
        time_s=time_s,
        gt_matches=None if gt is None else gt_match_counts(cuboids, gt),
        recall_counts=recall_counts(dist),
    )
    if parsimony_k is not None:
        k_max = max(int(parsimony_k), len(cuboids), 1)
        pad = k_max - max(len(cuboids), 1)  # k beyond the frame's cuboids: all of them, i.e. the plain value
        m.prefix_coverage = (prefix_cov or [0.0]) + [m.coverage] * pad
        m.prefix_auc = {}
        for cm, full in auc_stats.items():
            curve = [AucStats.of(prefix_dist[:, k], cm / 100.0) for k in range(len(cuboids) - 1)]
            m.prefix_auc[cm] = curve + [full] * (pad + 1)
    if instances is not None and instances.shape != depth_m.shape:
        raise ValueError(
            f"instance image is {instances.shape[1]}x{instances.shape[0]} but the depth map is "
            f"{depth_m.shape[1]}x{depth_m.shape[0]}"
        )
    if instances is None and not shape:
        return m
    from cuboidcli.fitting.assign import assign_points

    cfg = config or FitConfig()
    labels = assign_points(points, cuboids, cfg.tau_sq_m2, cfg.beta, cfg.tau_c, cfg.occlusion_aware)
    if instances is not None:
        m.objects = object_counts(labels, instances[valid], len(cuboids))
    if shape:
        label_img = np.full(depth_m.shape, -3, dtype=np.int32)
        label_img[valid] = labels
        m.shape = shape_metrics(
            depth_m,
            camera,
            cuboids,
            label_img,
            math.sqrt(cfg.tau_sq_m2),
            fit_gravity=fit_gravity,
            known=known_gravity,
            estimate=(cfg.step_for(*depth_m.shape), cfg.seed),
        )
    return m


def _nanmean(values) -> float:
    v = np.array([x for x in values if x is not None], dtype=np.float64)
    v = v[np.isfinite(v)]
    return float(v.mean()) if v.size else math.nan


def _padded(curve: list, k_max: int) -> list:
    """A frame's curve extended to k_max with its last value (all of the frame's cuboids)."""
    return list(curve) + [curve[-1]] * (k_max - len(curve))


def parsimony_curve(frames: list[FrameMetrics]) -> dict | None:
    """Pooled parsimony curve of a run: {"k", auc keys, "coverage_pct"} as lists in reporting units.

    AUC pooled over all points of all frames per k; coverage the mean over frames per k. None unless every
    frame has its curve.
    """
    if not frames or any(f.prefix_coverage is None or f.prefix_auc is None for f in frames):
        return None
    k_max = max(len(f.prefix_coverage) for f in frames)
    out: dict = {"k": list(range(1, k_max + 1))}
    for cm in frames[0].prefix_auc:
        curves = [_padded(f.prefix_auc[cm], k_max) for f in frames]
        pooled = []
        for k in range(k_max):
            stats = curves[0][k]
            for c in curves[1:]:
                stats = stats.merge(c[k])
            pooled.append(100.0 * stats.value)
        out[auc_key(cm)] = pooled
    cov = np.array([_padded(f.prefix_coverage, k_max) for f in frames], dtype=np.float64)
    out["coverage_pct"] = (100.0 * cov.mean(axis=0)).tolist()
    return out


def aggregate(frames: list[FrameMetrics], curves: bool = True) -> dict:
    """Aggregates of one run in reporting units, keys in the paper's column order (see module docstring).

    ``curves``: include the parsimony curve (key "parsimony") when the frames have it.
    """
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
    with_objects = [f for f in frames if f.objects is not None]
    if with_objects:
        totals = [sum(f.objects[i] for f in with_objects) for i in range(4)]
        out.update(object_rates(*totals))
        out["objects_eligible"] = totals[1]
    out["frames"] = len(frames)
    out["frames_without_cuboids"] = sum(1 for f in frames if f.cuboids == 0)
    out["frames_with_gt"] = len(with_gt)
    if with_objects:
        out["frames_with_instances"] = len(with_objects)
    box = [f.gt_matches[BOX_IOU] for f in with_gt if BOX_IOU in f.gt_matches]
    if box:
        out.update(box_rates(*(sum(c[i] for c in box) for i in range(3))))
    shapes = [f.shape for f in frames if f.shape is not None]
    if shapes:
        out.update(shape_summary(shapes))
        for source in SOURCES:
            out[f"frames_gravity_{source}"] = sum(1 for s in shapes if s.reference == source)
        out.update(gravity_summary(shapes))
    if curves and (curve := parsimony_curve(frames)) is not None:
        out["parsimony"] = curve
    return out


def _mean_std_curves(curves: list[dict]) -> tuple[dict, dict]:
    """Element-wise mean and population std over runs of parsimony curves (shorter ones padded)."""
    k_max = max(len(c["k"]) for c in curves)
    mean: dict = {"k": list(range(1, k_max + 1))}
    std: dict = {"k": list(range(1, k_max + 1))}
    for key in curves[0]:
        if key == "k":
            continue
        vals = np.array([_padded(c[key], k_max) for c in curves], dtype=np.float64)
        with np.errstate(invalid="ignore"):
            mean[key], std[key] = vals.mean(axis=0).tolist(), vals.std(axis=0).tolist()
    return mean, std


def mean_std(runs: list[dict]) -> dict[str, tuple]:
    """Mean and population std (ddof 0) of each aggregate over runs, like the paper's tables.

    The parsimony curve ("parsimony") gives a pair of dicts of lists: (mean per k, std per k).
    """
    out: dict = {}
    for key in runs[0]:
        if key == "parsimony":
            curves = [r["parsimony"] for r in runs if "parsimony" in r]
            out[key] = _mean_std_curves(curves)
            continue
        vals = np.array([r.get(key, math.nan) for r in runs], dtype=np.float64)
        fin = vals[np.isfinite(vals)]
        out[key] = (float(fin.mean()), float(fin.std())) if fin.size else (math.nan, math.nan)
    return out

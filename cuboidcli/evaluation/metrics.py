"""The paper's metrics (Sec. 4 "Metrics", Table 1) per frame and aggregated over frames.

Per frame, on all valid full-resolution depth points:

- ``cuboids``: |M|.
- ``coverage``: fraction of image pixels covered by a projected cuboid (:mod:`.coverage`).
- ``oa_all_m``: mean OA-L2 distance (:mod:`.oa`) over the frame's valid points.
- ``oa_covered_m``: the same over valid points whose pixel is covered; undefined (NaN) with no such point.
- AUC@X: area under the recall curve of the OA distances up to X, divided by X (:mod:`.auc`).

Aggregated over the frames of a run (as the paper) by :func:`.aggregate.aggregate`: |M|, coverage and time
are means over frames; OA "all" is the mean of the per-frame means; OA "covered" the mean over frames with
covered points; AUC is POOLED over all points of all frames, not averaged over frames.

Further measurements (computed by ``cuboids evaluate``; optional arguments of :func:`frame_metrics`):

- **Parsimony curve**: AUC@X and coverage of the first k cuboids in selection order (the order of the
  list), k = 1..K (K = ``config.max_cuboids``, or more if a frame has more cuboids). A frame with fewer than
  k cuboids uses all of them. AUC is pooled over all points of all frames and coverage averaged over
  frames, exactly like the plain values, which the curve reaches at k = K. The per-cuboid OA terms are
  computed once per frame (:func:`.oa.oa_sq_prefix_distances`) and the coverage masks once per cuboid.
- **Object recall / precision** where a per-pixel instance image exists (synthetic data,
  :mod:`.object_recall`): every valid full-resolution point is assigned to a cuboid with the estimator's
  own rule (:func:`cuboidcli.fitting.assign.assign_points`, the config's tau, beta, tau_c and OAI setting)
  and an eligible ground-truth object is explained by a cuboid that holds at least half of it while at least
  half of the cuboid's points lie on it.
- **Shape** (``shape=True``, :mod:`.shape`): per cuboid the angle of its axes to the up vector and to the
  room's Manhattan axes and the support of its visible faces by its inliers (the same assignment); per
  frame the gravity error where the gravity is known. Pooled over the cuboids (medians, support mean)
  and frames (gravity error) of a run by :func:`shape_summary` and :func:`gravity_summary`. With ground
  truth also ``box_recall_iou25_pct`` / ``box_precision_iou25_pct`` (the IoU 0.25 matching of :mod:`.iou`,
  renamed).

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

import numpy as np

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.auc import (
    AUC_CM,
    AucStats,
    auc_key,
    recall_counts,
)
from cuboidcli.evaluation.coverage import fill_convex, projected_hull
from cuboidcli.evaluation.iou import BOX_IOU, box_rates, gt_match_counts, match_rates
from cuboidcli.evaluation.oa import oa_distances, oa_sq_prefix_distances
from cuboidcli.evaluation.object_recall import (
    ObjectCounts,
    object_counts,
    object_rates,
)
from cuboidcli.evaluation.shape import Reference, ShapeMetrics, shape_metrics
from cuboidcli.evaluation.shape_summary import shape_summary
from cuboidcli.fitting.box import score_params
from cuboidcli.fitting.config import FitConfig
from cuboidcli.geometry.gravity import Gravity


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
        r.update(match_rates(self.gt_matches or {}))
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
    labels = assign_points(points, cuboids, score_params(cfg))
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

"""Metrics of a room abstraction: predicted cuboids in the world frame against a room's ground truth.

The frame metrics of :mod:`.metrics` measure one depth map with occlusion-aware distances from its
camera; a room has no single camera, so here every evaluation point (e.g. the voxelised exact depth of a
scan, :func:`cuboidcli.synth.scan.truth_points`) is measured by its plain distance to the nearest cuboid
SURFACE (:func:`point_box_distance`; a point inside a box is as far as that box's nearest face). From it:

- AUC@20 cm and AUC@5 cm (:func:`.metrics.auc`, in %) and the mean distance (cm; infinite without cuboids).
- Object recall / precision by the mutual-majority rule of :func:`.metrics.object_counts`: each point
  belongs to its nearest cuboid when that surface is within ``inlier_m``, else to none; an object (any
  nonzero instance id, shell slabs too) with >= 1 % of the points is eligible; a cuboid explains it when it
  holds >= 50 % of the object's points and >= 50 % of its own points lie on the object.
- Box recall at 3D IoU 0.25 and 0.5 (greedy one-to-one matching, :func:`.iou.greedy_matches`), kind-aware:
  ground-truth boxes of kind ``object`` are matched with predicted boxes of kind ``object``, the shell
  (floor, wall, ceiling) with the predicted shell; precision counts the predicted boxes of each group.
"""

from __future__ import annotations

import math

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.iou import box_iou, greedy_matches
from cuboidcli.evaluation.metrics import auc, auc_key, object_counts, object_rates

SHELL_KINDS = frozenset({"floor", "wall", "ceiling"})
#: IoU thresholds of the box recall (the precision uses the same matchings).
IOU_THRESHOLDS = (0.25, 0.5)
#: AUC upper bounds, metres (the paper's indoor values).
AUC_M = (0.20, 0.05)

#: The two groups of boxes matched by IoU: (key prefix, count key suffix, cuboid kinds).
_GROUPS = (("object", "objects", frozenset({"object"})), ("shell", "shell", SHELL_KINDS))
#: Row keys that are counts, summed by :func:`aggregate_scenes` (with every ``*_matches_iou*``).
_COUNTS = frozenset(
    {"objects_explained", "objects_eligible", "cuboids_explaining", "gt_objects", "pred_objects"}
    | {"gt_shell", "pred_shell"}
)


def surface_distances(points: np.ndarray, cuboids: list[Cuboid]) -> tuple[np.ndarray, np.ndarray]:
    """Distance (M,) metres of points (M, 3) to the nearest cuboid surface and that cuboid's index (M,)
    (the first on ties); inf and -1 without cuboids.

    In a box's local frame with q = |R^T (p - c)| - half_size, a point outside is ||max(q, 0)|| from the
    box and a point inside (all q <= 0) is -max(q) from its nearest face: together |signed distance|.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    best = np.full(len(points), np.inf)
    index = np.full(len(points), -1, dtype=np.int64)
    for k, c in enumerate(cuboids):  # one box at a time: memory stays O(M) for large clouds
        q = np.abs((points - c.center) @ c.rotation) - c.half_size
        d = np.linalg.norm(np.maximum(q, 0.0), axis=1) - np.minimum(q.max(axis=1), 0.0)
        closer = d < best
        best[closer], index[closer] = d[closer], k
    return best, index


def point_box_distance(points: np.ndarray, cuboids: list[Cuboid]) -> np.ndarray:
    """Distance (M,) metres of every point (M, 3) to the nearest cuboid surface; inf without cuboids."""
    return surface_distances(points, cuboids)[0]


def _iou_matrix(pred: list[Cuboid], gt: list[Cuboid]) -> np.ndarray:
    """(len(pred), len(gt)) IoU as :func:`.iou.iou_matrix`, skipping pairs whose circumscribed spheres
    are apart (their IoU is 0): a room has dozens of boxes and the exact IoU costs about a millisecond."""
    out = np.zeros((len(pred), len(gt)))
    if not pred or not gt:
        return out
    pc, gc = np.stack([p.center for p in pred]), np.stack([g.center for g in gt])
    pr = np.linalg.norm(np.stack([p.half_size for p in pred]), axis=1)
    gr = np.linalg.norm(np.stack([g.half_size for g in gt]), axis=1)
    near = np.linalg.norm(pc[:, None] - gc[None], axis=2) < pr[:, None] + gr[None]
    for i, j in zip(*np.nonzero(near), strict=True):
        out[i, j] = box_iou(pred[i], gt[j])
    return out


def _ratio(num: float, den: float) -> float:
    return 100.0 * num / den if den else math.nan


def _box_matches(pred: list[Cuboid], gt: list[Cuboid], thresholds) -> dict[float, int]:
    ious = _iou_matrix(pred, gt)
    return {float(t): len(greedy_matches(ious, t)) for t in thresholds}


def scene_metrics(
    pred: list[Cuboid],
    gt: list[Cuboid],
    points: np.ndarray,
    instance: np.ndarray,
    inlier_m: float = 0.05,
    iou_thresholds=IOU_THRESHOLDS,
) -> dict:
    """The metrics of one room (module docstring) as a flat row in reporting units (%, cm).

    ``pred`` and ``gt`` are cuboids in one frame (the world's, metres), ``points`` (M, 3) the evaluation
    points in that frame and ``instance`` (M,) their ground-truth object ids (0 = no object). Ratios with
    a zero denominator are NaN. Keys: ``n_cuboids``, ``points``, ``auc20cm_pct``, ``auc5cm_pct``,
    ``mean_distance_cm``; ``object_recall_pct``, ``object_precision_pct`` and their counts
    ``objects_explained``, ``objects_eligible``, ``cuboids_explaining``; per IoU threshold t (``t:g``,
    e.g. 0.25) ``object_box_recall_iou{t}_pct``, ``object_box_precision_iou{t}_pct``,
    ``object_matches_iou{t}``, ``shell_box_recall_iou{t}_pct``, ``shell_box_precision_iou{t}_pct``,
    ``shell_matches_iou{t}``; and ``gt_objects``, ``pred_objects``, ``gt_shell``, ``pred_shell``.
    """
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    instance = np.asarray(instance).ravel()
    if len(instance) != len(points):
        raise ValueError(f"{len(instance)} instance ids for {len(points)} points")
    dist, nearest = surface_distances(points, pred)
    row: dict = {"n_cuboids": len(pred), "points": len(points)}
    for t in AUC_M:
        row[auc_key(100.0 * t)] = 100.0 * auc(dist, t)
    row["mean_distance_cm"] = 100.0 * float(dist.mean()) if len(points) else math.nan
    labels = np.where(dist <= inlier_m, nearest, -1)
    counts = object_counts(labels, instance, len(pred))
    row.update(object_rates(*counts))
    row.update(
        objects_explained=counts.explained,
        objects_eligible=counts.eligible,
        cuboids_explaining=counts.explaining,
    )
    for name, plural, kinds in _GROUPS:
        p, g = [c for c in pred if c.kind in kinds], [c for c in gt if c.kind in kinds]
        row[f"gt_{plural}"], row[f"pred_{plural}"] = len(g), len(p)
        for t, m in _box_matches(p, g, iou_thresholds).items():
            row[f"{name}_box_recall_iou{t:g}_pct"] = _ratio(m, len(g))
            row[f"{name}_box_precision_iou{t:g}_pct"] = _ratio(m, len(p))
            row[f"{name}_matches_iou{t:g}"] = m
    return row


def _pooled(rows: list[dict]) -> dict:
    """The ratio metrics recomputed from the counts summed over rows."""

    def total(key: str) -> int:
        return sum(int(r[key]) for r in rows)

    out = object_rates(
        total("objects_explained"), total("objects_eligible"), total("cuboids_explaining"), total("n_cuboids")
    )
    for key in rows[0]:
        for name, plural, _ in _GROUPS:
            prefix = f"{name}_matches_iou"
            if key.startswith(prefix):
                t, m = key[len(prefix) :], total(key)
                out[f"{name}_box_recall_iou{t}_pct"] = _ratio(m, total(f"gt_{plural}"))
                out[f"{name}_box_precision_iou{t}_pct"] = _ratio(m, total(f"pred_{plural}"))
    return out


def aggregate_scenes(rows: list[dict]) -> dict:
    """Aggregate the rows of :func:`scene_metrics` over rooms.

    Ratios of counts (object recall / precision, box recall / precision) are pooled: recomputed from the
    counts summed over the rooms, so a room with many objects weighs more. Counts are summed. Every other
    number (cuboids, points, AUC, mean distance) is the mean over the rooms where it is not NaN (an
    infinite mean distance, a room without cuboids, keeps the mean infinite). ``scenes``: how many rows.
    """
    if not rows:
        return {"scenes": 0}
    pooled = _pooled(rows)
    summed = {k for k in rows[0] if k in _COUNTS or "_matches_iou" in k}
    out: dict = {"scenes": len(rows)}
    for key in rows[0]:
        if key in pooled:
            out[key] = pooled[key]
        elif key in summed:
            out[key] = sum(int(r[key]) for r in rows)
        else:
            v = np.array([float(r[key]) for r in rows])
            v = v[~np.isnan(v)]
            out[key] = float(v.mean()) if v.size else math.nan
    return out

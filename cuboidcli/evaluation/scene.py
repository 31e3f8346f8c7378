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
- Box recall at IoU 0.25 and 0.5 (greedy one-to-one matching, :func:`.iou.greedy_matches`), kind-aware:
  ground-truth boxes of kind ``object`` are matched by 3D IoU with the fit's whole-object boxes
  (:mod:`cuboidcli.fitting.objects`; ``object_box_*``) and, for reference, with its cuboids of kind
  ``object`` (the parts: ``part_box_*``); the shell (floor, wall, ceiling) with the predicted shell by the
  PLANAR IoU of :func:`planar_iou`; precision counts the predicted boxes of each group. A method without
  object boxes (the Open3D baseline) is scored on its object cuboids in both.

Why the shell is not matched in 3D: a ground-truth shell slab is 5 cm thick and lies just outside the room,
while a fitted slab is a few millimetres thick on the surface it explains. Their 3D IoU measures the two
thicknesses (and is 0 when the slabs only touch), not whether the wall was found. Two shell slabs match
when their thin axes are parallel within :data:`SHELL_ANGLE_DEG` and their mid-planes are within
:data:`SHELL_OFFSET_M`; the score is then the IoU of their rectangles in the ground truth's plane.
"""

from __future__ import annotations

import math

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.auc import auc, auc_key
from cuboidcli.evaluation.iou import box_iou, greedy_matches
from cuboidcli.evaluation.object_recall import object_counts, object_rates

SHELL_KINDS = frozenset({"floor", "wall", "ceiling"})
#: IoU thresholds of the box recall (the precision uses the same matchings).
IOU_THRESHOLDS = (0.25, 0.5)
#: AUC upper bounds, metres (the paper's indoor values).
AUC_M = (0.20, 0.05)
#: Shell slabs match only when their thin axes are parallel within this angle, degrees ...
SHELL_ANGLE_DEG = 10.0
#: ... and the predicted slab's centre is within this distance of the ground truth's mid-plane, metres.
SHELL_OFFSET_M = 0.10

#: Row keys that are counts, summed by :func:`aggregate_scenes` (with every ``*_matches_iou*``).
_COUNTS = frozenset(
    {"objects_explained", "objects_eligible", "cuboids_explaining", "gt_objects", "pred_objects"}
    | {"gt_parts", "pred_parts", "gt_shell", "pred_shell"}
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


def near_iou_matrix(pred: list[Cuboid], gt: list[Cuboid]) -> np.ndarray:
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


#: A rectangle's corners as signs of its two half-sizes, in cyclic order.
_RECT_SIGNS = np.array([[1.0, 1.0], [-1.0, 1.0], [-1.0, -1.0], [1.0, -1.0]])


def slab_plane(box: Cuboid) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A box seen as a slab: the unit normal (3,) of its mid-plane (its thinnest axis), the two other axes
    (3, 2) spanning that plane and their half-sizes (2,), metres. The mid-plane passes through the centre."""
    thin = int(np.argmin(box.half_size))
    others = [k for k in range(3) if k != thin]
    return box.rotation[:, thin], box.rotation[:, others], box.half_size[others]


def _clip(poly: np.ndarray, axis: int, sign: float, limit: float) -> np.ndarray:
    """The part of a convex polygon (K, 2), cyclic order, with sign * x[axis] <= limit (one step of
    Sutherland-Hodgman); the result keeps the cyclic order."""
    out = []
    for i in range(len(poly)):
        a, b = poly[i], poly[(i + 1) % len(poly)]
        da, db = sign * a[axis] - limit, sign * b[axis] - limit
        if da <= 0.0:
            out.append(a)
        if da * db < 0.0:  # the edge crosses the line: keep the crossing point
            out.append(a + da / (da - db) * (b - a))
    return np.array(out).reshape(-1, 2)


def _area(poly: np.ndarray) -> float:
    """Area of a polygon (K, 2) in cyclic order (either orientation), by the shoelace formula."""
    if len(poly) < 3:
        return 0.0
    x, y = poly[:, 0], poly[:, 1]
    return 0.5 * abs(float(x @ np.roll(y, -1) - y @ np.roll(x, -1)))


def planar_iou(
    pred: Cuboid, gt: Cuboid, max_angle_deg: float = SHELL_ANGLE_DEG, max_offset_m: float = SHELL_OFFSET_M
) -> float:
    """IoU in [0, 1] of two slabs in the ground truth's plane, regardless of their thickness; 0 when the
    slabs are not in one plane.

    The slabs are in one plane when their thin axes (:func:`slab_plane`) are parallel within
    ``max_angle_deg`` (either direction) and ``pred``'s centre is within ``max_offset_m`` metres of
    ``gt``'s mid-plane. Then ``pred``'s mid-plane rectangle is projected onto ``gt``'s plane (a
    parallelogram, in ``gt``'s in-plane axes) and intersected with ``gt``'s rectangle: the IoU of their
    areas, both as seen in that plane.
    """
    normal_p, axes_p, half_p = slab_plane(pred)
    normal_g, axes_g, half_g = slab_plane(gt)
    if abs(float(normal_p @ normal_g)) < np.cos(np.radians(max_angle_deg)):
        return 0.0
    if abs(float(normal_g @ (pred.center - gt.center))) > max_offset_m:
        return 0.0
    corners = pred.center + (_RECT_SIGNS * half_p) @ axes_p.T  # (4, 3) world metres
    poly = (corners - gt.center) @ axes_g  # (4, 2) in gt's plane, gt's rectangle is centred at 0
    inter = poly
    for axis in (0, 1):
        for sign in (1.0, -1.0):
            inter = _clip(inter, axis, sign, float(half_g[axis]))
    overlap = _area(inter)
    union = _area(poly) + 4.0 * float(half_g[0] * half_g[1]) - overlap
    return 0.0 if union <= 0.0 else min(1.0, overlap / union)


def _planar_iou_matrix(pred: list[Cuboid], gt: list[Cuboid]) -> np.ndarray:
    """(len(pred), len(gt)) :func:`planar_iou` of every pair (a room has a dozen shell slabs)."""
    return np.array([[planar_iou(p, g) for g in gt] for p in pred]).reshape(len(pred), len(gt))


#: The two groups of boxes matched one to one: (key prefix, count key suffix, cuboid kinds, IoU matrix).
_GROUPS = (
    ("object", "objects", frozenset({"object"}), near_iou_matrix),
    ("part", "parts", frozenset({"object"}), near_iou_matrix),
    ("shell", "shell", SHELL_KINDS, _planar_iou_matrix),
)


def _ratio(num: float, den: float) -> float:
    return 100.0 * num / den if den else math.nan


def _box_matches(ious: np.ndarray, thresholds) -> dict[float, int]:
    return {float(t): len(greedy_matches(ious, t)) for t in thresholds}


def scene_metrics(
    pred: list[Cuboid],
    gt: list[Cuboid],
    points: np.ndarray,
    instance: np.ndarray,
    inlier_m: float = 0.05,
    iou_thresholds=IOU_THRESHOLDS,
    objects: list[Cuboid] | None = None,
) -> dict:
    """The metrics of one room (module docstring) as a flat row in reporting units (%, cm).

    ``pred`` and ``gt`` are cuboids in one frame (the world's, metres), ``points`` (M, 3) the evaluation
    points in that frame and ``instance`` (M,) their ground-truth object ids (0 = no object). Ratios with
    a zero denominator are NaN. Keys: ``n_cuboids``, ``points``, ``auc20cm_pct``, ``auc5cm_pct``,
    ``mean_distance_cm``; ``object_recall_pct``, ``object_precision_pct`` and their counts
    ``objects_explained``, ``objects_eligible``, ``cuboids_explaining``; per IoU threshold t (``t:g``,
    e.g. 0.25) ``object_box_recall_iou{t}_pct``, ``object_box_precision_iou{t}_pct``,
    ``object_matches_iou{t}``, ``shell_box_recall_iou{t}_pct``, ``shell_box_precision_iou{t}_pct``,
    ``shell_matches_iou{t}``, the same with ``part`` for the object cuboids; and ``gt_objects``,
    ``pred_objects``, ``gt_parts``, ``pred_parts``, ``gt_shell``, ``pred_shell``. ``objects``: the fit's
    whole-object boxes (None: its object cuboids stand for them).
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
    for name, plural, kinds, iou_matrix in _GROUPS:
        p, g = [c for c in pred if c.kind in kinds], [c for c in gt if c.kind in kinds]
        if name == "object" and objects is not None:
            p = list(objects)
        row[f"gt_{plural}"], row[f"pred_{plural}"] = len(g), len(p)
        for t, m in _box_matches(iou_matrix(p, g), iou_thresholds).items():
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
        for name, plural, *_ in _GROUPS:
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

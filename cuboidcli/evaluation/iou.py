"""Exact 3D IoU of oriented boxes and greedy one-to-one matching against ground-truth cuboids.

The intersection of two boxes is a convex polytope. We start from box A as six face polygons and clip it
by the six half-spaces of box B (Sutherland-Hodgman per face, plus a cap polygon on each cutting plane).
Its volume is the sum over faces of the fan tetrahedra spanned with an interior point (the vertex mean),
which needs each face's vertices in cyclic order but not a consistent orientation.

Ground-truth cuboid recall and precision count the greedy matches at each IoU threshold
(:func:`gt_match_counts`); ``box_recall_iou25_pct`` / ``box_precision_iou25_pct`` are those at
:data:`BOX_IOU` (:func:`box_rates`).
"""

from __future__ import annotations

import math

import numpy as np

from cuboidcli.cuboid import Cuboid

#: IoU thresholds of the ground-truth cuboid recall/precision.
IOU_THRESHOLDS = (0.25, 0.5)
#: The IoU threshold of ``box_recall_iou25_pct`` / ``box_precision_iou25_pct``.
BOX_IOU = 0.25

# Corner k of Cuboid.corners() has local signs from bits (x: 4, y: 2, z: 1); each face in cyclic order.
_FACES = ((0, 1, 3, 2), (4, 5, 7, 6), (0, 1, 5, 4), (2, 3, 7, 6), (0, 2, 6, 4), (1, 3, 7, 5))


def _clip_polygon(poly: np.ndarray, normal: np.ndarray, offset: float, tol: float):
    """Part of polygon (K, 3) with normal . x <= offset, and its points on the plane: ((K', 3), [(3,)])."""
    s = poly @ normal - offset
    out, on_plane = [], []
    k = len(poly)
    for i in range(k):
        j = (i + 1) % k
        if s[i] <= tol:
            out.append(poly[i])
            if s[i] >= -tol:
                on_plane.append(poly[i])
        if (s[i] < -tol and s[j] > tol) or (s[i] > tol and s[j] < -tol):
            x = poly[i] + (s[i] / (s[i] - s[j])) * (poly[j] - poly[i])
            out.append(x)
            on_plane.append(x)
    return (np.array(out) if len(out) >= 3 else None), on_plane


def _order_on_plane(points: np.ndarray, normal: np.ndarray) -> np.ndarray:
    """Points (K, 3) on a plane sorted by angle around their mean: a cyclic order of their convex hull."""
    centre = points.mean(axis=0)
    u = np.cross(normal, [1.0, 0.0, 0.0] if abs(normal[0]) < 0.9 else [0.0, 1.0, 0.0])
    u /= np.linalg.norm(u)
    w = np.cross(normal, u)
    rel = points - centre
    return points[np.argsort(np.arctan2(rel @ w, rel @ u))]


def _volume(faces: list[np.ndarray]) -> float:
    """Volume of a convex polytope given as face polygons (each (K, 3) in cyclic order), m^3."""
    if not faces:
        return 0.0
    centre = np.concatenate(faces).mean(axis=0)
    total = 0.0
    for f in faces:
        a = f[0] - centre
        b, c = f[1:-1] - centre, f[2:] - centre
        total += float(np.abs(np.einsum("k,nk->n", a, np.cross(b, c))).sum())
    return total / 6.0


def intersection_volume(a: Cuboid, b: Cuboid) -> float:
    """Volume of the intersection of two oriented boxes, m^3 (exact up to rounding)."""
    corners = a.corners()
    faces = [corners[list(f)] for f in _FACES]
    scale = float(max(a.half_size.max(), b.half_size.max(), 1e-9))
    tol = 1e-12 * scale
    for axis in range(3):
        for sign in (1.0, -1.0):
            normal = sign * b.rotation[:, axis]
            offset = float(normal @ b.center + b.half_size[axis])
            if max(float((f @ normal).max()) for f in faces) <= offset + tol:
                continue  # nothing beyond this plane: no cut, no cap
            clipped, cap = [], []
            for f in faces:
                poly, on_plane = _clip_polygon(f, normal, offset, tol)
                if poly is not None:
                    clipped.append(poly)
                cap.extend(on_plane)
            if len(cap) >= 3:
                clipped.append(_order_on_plane(np.array(cap), normal))
            faces = clipped
            if not faces:
                return 0.0
    return _volume(faces)


def box_iou(a: Cuboid, b: Cuboid) -> float:
    """3D intersection over union of two oriented boxes, in [0, 1]."""
    inter = intersection_volume(a, b)
    union = a.volume() + b.volume() - inter
    return 0.0 if union <= 0.0 else min(1.0, inter / union)


def iou_matrix(pred: list[Cuboid], gt: list[Cuboid]) -> np.ndarray:
    """IoU of every predicted against every ground-truth cuboid: (len(pred), len(gt))."""
    return np.array([[box_iou(p, g) for g in gt] for p in pred]).reshape(len(pred), len(gt))


def greedy_matches(ious: np.ndarray, threshold: float) -> list[tuple[int, int]]:
    """One-to-one (pred, gt) pairs with IoU >= threshold, taking the highest IoU first."""
    pairs = [
        (float(ious[i, j]), i, j)
        for i in range(ious.shape[0])
        for j in range(ious.shape[1])
        if ious[i, j] >= threshold
    ]
    used_p, used_g, out = set(), set(), []
    for _, i, j in sorted(pairs, key=lambda t: (-t[0], t[1], t[2])):
        if i not in used_p and j not in used_g:
            used_p.add(i)
            used_g.add(j)
            out.append((i, j))
    return out


def gt_match_counts(pred: list[Cuboid], gt: list[Cuboid], thresholds=IOU_THRESHOLDS) -> dict:
    """(matched, |GT|, |pred|) per IoU threshold, with a greedy one-to-one matching."""
    ious = iou_matrix(pred, gt)
    return {float(t): (len(greedy_matches(ious, t)), len(gt), len(pred)) for t in thresholds}


def _rates(matched: int, n_gt: int, n_pred: int, recall_key: str, precision_key: str) -> dict:
    """Recall matched / |GT| and precision matched / |pred| in % (NaN with a zero denominator)."""
    return {
        recall_key: 100.0 * matched / n_gt if n_gt else math.nan,
        precision_key: 100.0 * matched / n_pred if n_pred else math.nan,
    }


def match_rates(counts: dict) -> dict:
    """``recall_iou{t}_pct`` and ``precision_iou{t}_pct`` per IoU threshold t of ``counts`` ({t: (matched,
    |GT|, |pred|)} as :func:`gt_match_counts` gives, of a frame or summed over frames)."""
    out: dict = {}
    for thr, (matched, n_gt, n_pred) in counts.items():
        out.update(_rates(matched, n_gt, n_pred, f"recall_iou{thr:g}_pct", f"precision_iou{thr:g}_pct"))
    return out


def box_rates(matched: int, n_gt: int, n_pred: int) -> dict:
    """Ground-truth box recall and precision at IoU :data:`BOX_IOU` in % (NaN with a zero denominator)."""
    return _rates(matched, n_gt, n_pred, "box_recall_iou25_pct", "box_precision_iou25_pct")

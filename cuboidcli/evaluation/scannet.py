"""Real room scans with labelled furniture boxes, in the layout of ScanNet's detection data (VoteNet's
``scannet_train_detection_data``): each scan NAME of a folder is ``NAME.ply`` or ``NAME_vert.npy`` (the
points, (N, 6): x y z r g b, metres, z up), ``NAME_bbox.npy`` (K, 7: centre, full size, NYU40 class id of
axis-aligned furniture boxes), ``NAME_ins_label.npy`` and ``NAME_sem_label.npy`` ((N,) instance id, 0 =
none, and NYU40 class of each point of ``NAME_vert.npy``).

Every scan is fitted as ``cuboids fit NAME.ply`` fits it, with the fitter's settings (:func:`fit_scan`),
and its result is scored against the labels:

- **Recall at IoU t** (0.25, 0.5): the labelled boxes matched one to one (greedy, highest IoU first,
  :func:`.iou.greedy_matches`) by the result's whole-object boxes (``objects`` in the JSON) with a 3D IoU
  of at least t, over the labelled boxes; per class at 0.25 as well.
- **Precision**: the share of object boxes that lie on one labelled object: at least
  :data:`ON_OBJECT_SHARE` of the scan's points inside the box belong to a single instance of a labelled
  class (one of :data:`BOX_CLASSES`). A fragment of a cabinet counts (it lies on one object; recall at
  IoU is what fragmenting costs); a box over two chairs, over a wall or over unlabelled clutter does not.
  A box with no point inside it does not.
- **AP at IoU t**: class-agnostic average precision of the object boxes ranked by their ``score``, as in
  the detection literature (VoteNet's evaluation): in each scan the boxes are taken by falling score and
  each is a hit when its best-overlapping labelled box has IoU >= t and was not hit before (PASCAL VOC's
  rule); the precision-recall curve of all scans' boxes by falling score is made monotone and integrated
  over recall (all points, not 11).
- **AUC@20 / AUC@5** of the scan's points' distances to the nearest cuboid surface (all cuboids, shell
  too; :func:`.scene.surface_distances`, :func:`.auc.auc`), the number of cuboids and object boxes, the
  seconds of the fit (reading included) and the angle between the fitted up direction and the normal of
  the points labelled floor (degrees; 180 when the fit turned the room upside down).

Pooled over scans, recalls, precisions and AP are recomputed from the summed counts and the joint
ranking; the up error is the largest; the other numbers are means over the scans.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace
from pathlib import Path

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.auc import auc, auc_key
from cuboidcli.evaluation.iou import greedy_matches
from cuboidcli.evaluation.scene import AUC_M, near_iou_matrix, surface_distances

#: The NYU40 classes ScanNet's furniture boxes are labelled with (the 18 of its detection benchmark).
BOX_CLASSES = {
    3: "cabinet", 4: "bed", 5: "chair", 6: "sofa", 7: "table", 8: "door", 9: "window", 10: "bookshelf",
    11: "picture", 12: "counter", 14: "desk", 16: "curtain", 24: "refrigerator", 28: "shower curtain",
    33: "toilet", 34: "sink", 36: "bathtub", 39: "other furniture",
}  # fmt: skip
#: IoU thresholds of recall and AP; per-class recall is at the first.
IOU_THRESHOLDS = (0.25, 0.5)
#: The NYU40 class of the floor.
FLOOR_CLASS = 2
#: An object box lies on one labelled object when at least this share of the points inside it do.
ON_OBJECT_SHARE = 0.5
_BOXES, _POINTS, _INSTANCE, _CLASS = "_bbox.npy", "_vert.npy", "_ins_label.npy", "_sem_label.npy"


def labelled_names(folder: str | os.PathLike) -> list[str]:
    """The names of ``folder`` that have a ``_bbox.npy``, sorted, whether or not their points are there: a
    folder in this layout (empty when ``folder`` is none)."""
    return sorted(p.name[: -len(_BOXES)] for p in Path(folder).glob(f"*{_BOXES}") if p.is_file())


def has_points(folder: str | os.PathLike, name: str) -> bool:
    """Whether scan ``name`` of ``folder`` has its points: a ``.ply`` or a ``_vert.npy``."""
    folder = Path(folder)
    return (folder / f"{name}.ply").is_file() or (folder / f"{name}{_POINTS}").is_file()


def scan_names(folder: str | os.PathLike) -> list[str]:
    """The scans of ``folder``, sorted: the names with a ``_bbox.npy`` and a ``.ply`` or ``_vert.npy``."""
    return [n for n in labelled_names(folder) if has_points(folder, n)]


def scan_input(folder: str | os.PathLike, name: str) -> Path:
    """The file a scan is fitted from: its ``.ply``, else its ``_vert.npy``."""
    ply = Path(folder) / f"{name}.ply"
    return ply if ply.is_file() else Path(folder) / f"{name}{_POINTS}"


@dataclass(frozen=True)
class ScanTruth:
    """The labels of one scan: ``points`` (N, 3) metres, ``boxes`` its labelled furniture (axis-aligned,
    kind ``object``), ``classes`` (K,) their NYU40 ids, ``instance`` and ``semantic`` (N,) per point (None
    without the per-point files: precision is then NaN)."""

    name: str
    points: np.ndarray
    boxes: list[Cuboid]
    classes: np.ndarray
    instance: np.ndarray | None
    semantic: np.ndarray | None
    up: np.ndarray = field(default_factory=lambda: np.array([0.0, 0.0, 1.0]))
    """(3,) the normal of the points labelled floor (:data:`FLOOR_CLASS`), facing the room (most of the scan's
    points lie on its side, whatever axis the file calls up); +z without them. Some scans' floors are
    tilted in their frame (by up to 15 degrees)."""


def read_truth(folder: str | os.PathLike, name: str) -> ScanTruth:
    """The labels of scan ``name`` of ``folder`` (module docstring); the points from ``_vert.npy``, else from
    the ``.ply``. Raises ValueError when the box or label arrays have the wrong shape."""
    folder = Path(folder)
    raw = np.load(folder / f"{name}{_BOXES}")
    if raw.ndim != 2 or raw.shape[1] != 7:
        raise ValueError(f"{name}{_BOXES}: expected (K, 7) boxes, got {raw.shape}")
    boxes = [Cuboid(b[:3], b[3:6] / 2.0, np.eye(3), kind="object") for b in raw]
    vert = folder / f"{name}{_POINTS}"
    if vert.is_file():
        points = np.load(vert)[:, :3].astype(np.float64)
    else:
        from cuboidcli.io.scan import read_scan

        points = read_scan(folder / f"{name}.ply").points
    labels = []
    for suffix in (_INSTANCE, _CLASS):
        path = folder / f"{name}{suffix}"
        labels.append(np.load(path).astype(np.int64).ravel() if vert.is_file() and path.is_file() else None)
        if labels[-1] is not None and len(labels[-1]) != len(points):
            raise ValueError(f"{name}{suffix}: {len(labels[-1])} labels for {len(points)} points")
    truth = ScanTruth(name, points, boxes, raw[:, 6].astype(np.int64), *labels)
    if truth.semantic is not None and np.sum(truth.semantic == FLOOR_CLASS) >= 100:
        return replace(truth, up=_floor_normal(points[truth.semantic == FLOOR_CLASS], points))
    return truth


def _floor_normal(floor: np.ndarray, points: np.ndarray, band_m: float = 0.03) -> np.ndarray:
    """(3,) the normal of the plane through points (N, 3) labelled floor, towards the median of the scan's
    ``points`` (M, 3) (a room stands on its floor): least squares, twice refitted on the points within
    ``band_m`` of it (a rug or a mislabelled box stays out)."""
    keep = np.ones(len(floor), dtype=bool)
    for _ in range(3):
        centre = floor[keep].mean(0)
        d = floor[keep] - centre
        normal = np.linalg.eigh(d.T @ d)[1][:, 0]
        near = np.abs((floor - centre) @ normal) < band_m
        if near.sum() < 100:
            break
        keep = near
    side = float(np.median(points @ normal) - floor[keep].mean(0) @ normal)
    return normal if side >= 0 else -normal


def fit_scan(fitter, path: str | os.PathLike):
    """Fit one scan file as ``cuboids fit`` does, with ``fitter``'s settings: the one call into the API."""
    return fitter.fit(path)


def _document(result) -> dict:
    """The "cuboids/1" JSON document of a :func:`fit_scan` result."""
    return result.record.to_json()


@dataclass
class ScanFit:
    """What the metrics read from a fitted scan's "cuboids/1" document (:func:`scan_fit`)."""

    cuboids: list[Cuboid]
    objects: list[Cuboid]
    scores: np.ndarray
    """(len(objects),) each object box's score (0 where the document has none)."""
    up: np.ndarray
    """(3,) the fitted up direction."""
    seconds: float
    stop_reason: str = ""


def scan_fit(doc: dict, seconds: float) -> ScanFit:
    """The cuboids, object boxes (with scores), up direction and stop reason of a "cuboids/1" document."""
    cuboids = [Cuboid.from_json(c) for c in doc.get("cuboids", [])]
    entries = doc.get("objects", [])
    objects = [Cuboid(o["center"], o["half_size"], np.asarray(o["rotation"]), kind="object") for o in entries]
    scores = np.array([float(o.get("score", 0.0)) for o in entries])
    up = np.asarray(doc.get("up", {}).get("up", [0.0, 0.0, 1.0]), dtype=np.float64)
    stop = str(doc.get("fit_info", {}).get("stop_reason", ""))
    return ScanFit(cuboids, objects, scores, up, seconds, stop)


def on_one_object(boxes: list[Cuboid], truth: ScanTruth) -> np.ndarray:
    """(len(boxes),) bool: whether each box lies on one labelled object (module docstring)."""
    if truth.instance is None or truth.semantic is None:
        return np.zeros(len(boxes), dtype=bool)
    labelled = np.isin(truth.semantic, list(BOX_CLASSES)) & (truth.instance > 0)
    ids = np.where(labelled, truth.instance, 0)
    out = np.zeros(len(boxes), dtype=bool)
    for k, b in enumerate(boxes):
        inside = np.all(np.abs((truth.points - b.center) @ b.rotation) <= b.half_size, axis=1)
        if inside.any():
            counts = np.bincount(ids[inside])
            counts[0] = 0
            out[k] = counts.max() >= ON_OBJECT_SHARE * inside.sum()
    return out


def detection_hits(ious: np.ndarray, scores: np.ndarray, threshold: float) -> np.ndarray:
    """(P,) bool: whether each predicted box (rows of ``ious`` (P, G)) is a hit at IoU ``threshold`` under
    PASCAL VOC's rule: by falling score, a box hits when its best-overlapping labelled box has IoU >=
    ``threshold`` and no higher-scored box hit it first."""
    hits = np.zeros(len(scores), dtype=bool)
    if ious.size == 0:
        return hits
    taken = np.zeros(ious.shape[1], dtype=bool)
    for i in np.argsort(-scores, kind="stable"):
        j = int(ious[i].argmax())
        if ious[i, j] >= threshold and not taken[j]:
            taken[j] = hits[i] = True
    return hits


def average_precision(scores: np.ndarray, hits: np.ndarray, n_truth: int) -> float:
    """Area under the precision-recall curve of boxes ranked by falling ``scores`` (P,) with ``hits`` (P,),
    against ``n_truth`` labelled boxes; precision made non-increasing in recall (all-point interpolation).
    NaN without labelled boxes."""
    if n_truth == 0:
        return math.nan
    order = np.argsort(-np.asarray(scores, dtype=np.float64), kind="stable")
    tp = np.cumsum(np.asarray(hits, dtype=np.float64)[order])
    recall = np.concatenate([[0.0], tp / n_truth, [tp[-1] / n_truth if len(tp) else 0.0]])
    precision = np.concatenate([[0.0], tp / np.arange(1, len(tp) + 1), [0.0]])
    precision = np.maximum.accumulate(precision[::-1])[::-1]
    return float(np.sum(np.diff(recall) * precision[1:]))


def _pct(num: float, den: float) -> float:
    return 100.0 * num / den if den else math.nan


def scan_metrics(fit: ScanFit, truth: ScanTruth) -> dict:
    """One scan's row (module docstring): ``scan``, ``cuboids``, ``objects``, ``labelled``,
    ``recall_iou{t}_pct``, ``matches_iou{t}``, ``ap_iou{t}_pct``, ``precision_pct``, ``on_object``,
    ``auc20cm_pct``, ``auc5cm_pct``, ``up_error_deg``, ``seconds``, ``stop_reason``; ``class_labelled`` and
    ``class_matched`` ({class name: count} at the first IoU threshold) and ``detections`` (score and hit
    per threshold of each object box, for the pooled AP)."""
    ious = near_iou_matrix(fit.objects, truth.boxes)
    row: dict = {"scan": truth.name, "cuboids": len(fit.cuboids), "objects": len(fit.objects)}
    row["labelled"] = len(truth.boxes)
    detections: dict = {"score": [float(s) for s in fit.scores]}
    for t in IOU_THRESHOLDS:
        pairs = greedy_matches(ious, t)
        row[f"matches_iou{t:g}"] = len(pairs)
        row[f"recall_iou{t:g}_pct"] = _pct(len(pairs), len(truth.boxes))
        hits = detection_hits(ious, fit.scores, t)
        detections[f"hit_iou{t:g}"] = [bool(h) for h in hits]
        row[f"ap_iou{t:g}_pct"] = 100.0 * average_precision(fit.scores, hits, len(truth.boxes))
        if t == IOU_THRESHOLDS[0]:
            matched = np.zeros(len(truth.boxes), dtype=bool)
            matched[[j for _, j in pairs]] = True
    on = on_one_object(fit.objects, truth)
    row["on_object"] = int(on.sum())
    row["precision_pct"] = _pct(on.sum(), len(fit.objects)) if truth.instance is not None else math.nan
    dist = surface_distances(truth.points, fit.cuboids)[0]
    for t in AUC_M:
        row[auc_key(100.0 * t)] = 100.0 * auc(dist, t)
    up = fit.up / max(float(np.linalg.norm(fit.up)), 1e-12)
    row["up_error_deg"] = math.degrees(math.acos(float(np.clip(up @ truth.up, -1.0, 1.0))))
    row["seconds"] = fit.seconds
    row["stop_reason"] = fit.stop_reason
    row["class_labelled"], row["class_matched"] = {}, {}
    for c, hit in zip(truth.classes, matched, strict=True):
        name = BOX_CLASSES.get(int(c), f"class {int(c)}")
        row["class_labelled"][name] = row["class_labelled"].get(name, 0) + 1
        row["class_matched"][name] = row["class_matched"].get(name, 0) + int(hit)
    row["detections"] = detections
    return row


def pool_rows(rows: list[dict]) -> dict:
    """The pooled row of scans' rows: recalls, precision and AP from the summed counts and the joint
    ranking of all object boxes; cuboids, objects, AUC, up error and seconds as means; class counts summed."""
    out: dict = {"scan": "pooled", "scans": len(rows)}
    if not rows:
        return out
    labelled = sum(r["labelled"] for r in rows)
    for key in ("cuboids", "objects", "labelled", "auc20cm_pct", "auc5cm_pct", "seconds"):
        out[key] = float(np.mean([r[key] for r in rows]))
    out["up_error_deg"] = float(np.max([r["up_error_deg"] for r in rows]))
    scores = np.concatenate([r["detections"]["score"] for r in rows]).astype(np.float64)
    for t in IOU_THRESHOLDS:
        out[f"recall_iou{t:g}_pct"] = _pct(sum(r[f"matches_iou{t:g}"] for r in rows), labelled)
        hits = np.concatenate([r["detections"][f"hit_iou{t:g}"] for r in rows]).astype(bool)
        out[f"ap_iou{t:g}_pct"] = 100.0 * average_precision(scores, hits, labelled)
    with_labels = [r for r in rows if not math.isnan(r["precision_pct"])]
    out["precision_pct"] = _pct(
        sum(r["on_object"] for r in with_labels), sum(r["objects"] for r in with_labels)
    )
    out["capped"] = sum(r["stop_reason"] == "max_cuboids" for r in rows)
    for key in ("class_labelled", "class_matched"):
        out[key] = {}
        for r in rows:
            for name, n in r[key].items():
                out[key][name] = out[key].get(name, 0) + n
    return out


#: ``progress(done, total, name, row)``: ``done`` scans of ``total`` are scored; called with ``row`` None as
#: scan ``name`` starts and with its row once it is scored.
ScanProgress = Callable[[int, int, str, "dict | None"], None]


def evaluate_scans(
    folder: str | os.PathLike,
    fitter,
    names: list[str] | None = None,
    progress: ScanProgress | None = None,
) -> tuple[list[dict], dict]:
    """Fit and score the scans ``names`` of ``folder`` (all of :func:`scan_names` by default) one after the
    other: (their rows, the pooled row). ``progress`` (:data:`ScanProgress`) before and after each scan."""
    names = list(names) if names is not None else scan_names(folder)
    rows: list[dict] = []
    for name in names:
        if progress is not None:
            progress(len(rows), len(names), name, None)
        truth = read_truth(folder, name)
        t = time.perf_counter()
        result = fit_scan(fitter, scan_input(folder, name))
        row = scan_metrics(scan_fit(_document(result), time.perf_counter() - t), truth)
        rows.append(row)
        if progress is not None:
            progress(len(rows), len(names), name, row)
    return rows, pool_rows(rows)


def class_recall(row: dict) -> dict[str, tuple[int, int]]:
    """{class name: (matched, labelled)} of a row or the pooled row, by falling number labelled."""
    labelled = row.get("class_labelled", {})
    return {n: (row["class_matched"].get(n, 0), k) for n, k in sorted(labelled.items(), key=lambda x: -x[1])}

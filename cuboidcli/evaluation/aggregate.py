"""The metrics of a run's frames aggregated, and of several runs as mean and std (the paper's tables).

Aggregated over the frames of a run (as the paper): |M|, coverage and time are means over frames; OA "all"
is the mean of the per-frame means; OA "covered" the mean over frames with covered points; AUC is POOLED
over all points of all frames, not averaged over frames (:class:`.auc.AucStats`); the ground-truth box and
object counts are summed over frames before the rates. The shape measurements pool over the cuboids and
the frames (:mod:`.shape_summary`); the parsimony curve as :func:`parsimony_curve` says.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING

import numpy as np

from cuboidcli.evaluation.auc import auc_key
from cuboidcli.evaluation.iou import BOX_IOU, box_rates, match_rates
from cuboidcli.evaluation.object_recall import object_rates
from cuboidcli.evaluation.shape import SOURCES
from cuboidcli.evaluation.shape_summary import gravity_summary, shape_summary

if TYPE_CHECKING:
    from cuboidcli.evaluation.metrics import FrameMetrics


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
        summed = {
            thr: tuple(sum(f.gt_matches[thr][i] for f in with_gt) for i in range(3))
            for thr in with_gt[0].gt_matches
        }
        out.update(match_rates(summed))
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

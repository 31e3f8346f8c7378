"""Standard monocular-depth error measures (Eigen et al. 2014), over the valid ground-truth pixels.

All functions take a predicted and a ground-truth depth map of the same shape ``(H, W)`` (or any shape) in
metres, numpy arrays or anything ``np.asarray`` accepts. A ground-truth pixel is valid when it is finite and
strictly positive (0 marks a hole, as in the depth PNGs); ``valid`` narrows the mask further. Predictions
must be finite on the valid pixels; a non-positive prediction counts as a miss (its ratio is infinite).
Computed in float64.
"""

from __future__ import annotations

import numpy as np

#: The usual thresholds of the delta accuracies (delta < 1.25, 1.25^2, 1.25^3).
DELTA = 1.25


def _pairs(pred, gt, valid) -> tuple[np.ndarray, np.ndarray]:
    """The (prediction, ground truth) values at the valid pixels, float64, 1-D."""
    pred = np.asarray(pred, dtype=np.float64)
    gt = np.asarray(gt, dtype=np.float64)
    if pred.shape != gt.shape:
        raise ValueError(f"prediction {pred.shape} and ground truth {gt.shape} differ in shape")
    mask = np.isfinite(gt) & (gt > 0)
    if valid is not None:
        valid = np.asarray(valid, dtype=bool)
        if valid.shape != gt.shape:
            raise ValueError(f"valid mask {valid.shape} and ground truth {gt.shape} differ in shape")
        mask &= valid
    if not mask.any():
        raise ValueError("no valid ground-truth pixels (all zero, NaN or masked out)")
    p, g = pred[mask], gt[mask]
    if not np.isfinite(p).all():
        raise ValueError("the prediction is NaN or infinite on valid ground-truth pixels")
    return p, g


def abs_rel(pred, gt, valid=None) -> float:
    """AbsRel = mean |d - d*| / d* over the valid pixels (dimensionless)."""
    p, g = _pairs(pred, gt, valid)
    return float(np.mean(np.abs(p - g) / g))


def rmse(pred, gt, valid=None) -> float:
    """RMSE = sqrt(mean (d - d*)^2) over the valid pixels, metres."""
    p, g = _pairs(pred, gt, valid)
    return float(np.sqrt(np.mean((p - g) ** 2)))


def delta_accuracy(pred, gt, valid=None, threshold: float = DELTA) -> float:
    """Fraction of valid pixels with max(d / d*, d* / d) < threshold (delta < 1.25 by default)."""
    p, g = _pairs(pred, gt, valid)
    with np.errstate(divide="ignore"):
        ratio = np.where(p > 0, np.maximum(p / g, g / np.where(p > 0, p, 1.0)), np.inf)
    return float(np.mean(ratio < threshold))


def depth_errors(pred, gt, valid=None) -> dict[str, float]:
    """All three measures and the number of pixels they were computed on:
    ``{"abs_rel", "rmse_m", "delta1", "valid_px"}``."""
    p, g = _pairs(pred, gt, valid)
    return {
        "abs_rel": abs_rel(p, g, None),
        "rmse_m": rmse(p, g, None),
        "delta1": delta_accuracy(p, g, None),
        "valid_px": int(g.size),
    }


def mean_errors(per_frame: list[dict[str, float]]) -> dict[str, float]:
    """Mean of each measure over frames (each frame weighs the same, the usual convention)."""
    if not per_frame:
        raise ValueError("no frames to average")
    keys = ("abs_rel", "rmse_m", "delta1")
    out = {k: float(np.mean([r[k] for r in per_frame])) for k in keys}
    out["frames"] = len(per_frame)
    return out

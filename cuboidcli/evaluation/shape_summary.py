"""The shape measurements of a run pooled: over its cuboids (axis angles, slab alignment, support:
:func:`shape_summary`) and over its frames (the gravity error: :func:`gravity_summary`)."""

from __future__ import annotations

import math

import numpy as np

from cuboidcli.evaluation.shape import GRAVITY_GOOD_DEG, ShapeMetrics


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

"""Depth discontinuities of a predicted depth map: the pixels to leave out of the fit.

A monocular network smears depth across object boundaries: between a chair at 2 m and the wall at 3 m
behind it, a band of pixels gets depths in between, and their back-projected points float in the air
between the two surfaces. :func:`depth_edge_mask` finds such pixels and :func:`drop_depth_edges` sets them
to 0 (missing) before the fit.

The test (why this and not a plain relative-jump threshold). For a pixel, take the disc of angular radius
``alpha`` around it and ``s = ln(max depth / min depth)`` over the disc's valid pixels. For any plane,
``ln Z`` changes across the image at a rate of ``tan(theta)`` per radian, ``theta`` being the angle between
the viewing ray and the plane's normal, so over a disc of angular diameter ``2 alpha`` a plane gives
``s <= ~2 alpha tan(theta)``. A pixel is flagged when ``s > 2 alpha tan(max_angle)``: its neighbourhood
changes depth faster than any surface seen at less than ``max_angle`` from its normal could. A smeared
step from 2 m to 3 m over 5 of the net's 320 columns (f ~ 260 px) is a "surface" at 87 degrees and is
flagged (as are the pixels within ``alpha`` of it, on both sides); a floor seen from 1.5 m height is at
69 degrees at 4 m and 79 degrees at 8 m and is not, however far it runs; nor are walls seen obliquely,
whose depth also changes smoothly. A plain ``(max - min) / min > t`` with a fixed ``t`` is the same test
with ``t`` tied to the window, and the angle says what the threshold means physically. Real surfaces seen
beyond ``max_angle`` are lost too, but they give few and noisy points anyway (the sensor loses them as
well). A second difference of inverse depth (zero on any plane) was not used: a smeared band several
pixels wide is itself a linear ramp, whose middle has no curvature.

Resolution: the map is subsampled (nearest) to ``work_width`` columns (the built-in network's own
resolution, 320) and the disc has ``radius`` working pixels, so a 640x480 frame and a 4032x3024 photo of
the same scene flag the same regions; the mask is scaled back (nearest). The angular size of a working
pixel comes from ``focal_px`` (the camera's focal length at the map's resolution; None assumes a 60 degree
horizontal field of view). Cost: the subsampling, two 5x5 morphological filters on 76,800 pixels, the
upscaling of the mask and one masked write at full resolution (about 20 ms at 12 MP on one core).

Missing depth (0, NaN, inf) stays missing and never makes an edge: the min/max filters see only valid
pixels, so a valid pixel next to a hole is judged on its valid neighbours alone.
"""

from __future__ import annotations

import math

import numpy as np

#: Defaults, from ``scripts/eval_depth_edges.py`` (default FitConfig, 3 seeds, cuboids fitted to the depth
#: predicted by depth_v3 and scored against the true depth; 6 real and 10 synthetic frames). No setting
#: tried (80/2, 85/2, 85/4 degrees/radius) beat fitting without the drop: AUC@20 real 14.8 % without, 14.4
#: / 14.5 / 14.5 % with; synthetic 25.2 % without, 25.0 / 24.2 / 24.6 % with (seed std 0.2-1.6). 85/2
#: loses least on the synthetic frames and its dropped pixels lie near true discontinuities 2x (real) and
#: 8x (synthetic) as often as pixels at random; 80 degrees drops 27 % of the real frames' pixels (the
#: network's texture-driven ripples) and 88 degrees almost none. With depth_v4 (smoother) 85/2 drops 0.7 %
#: of the real pixels and changes AUC@20 within the seeds' spread (17.1 -> 17.5 +- 0.7 %), so it stays off.
MAX_ANGLE_DEG = 85.0
RADIUS = 2
WORK_WIDTH = 320

_BIG = np.float32(1e30)


def _working_map(depth: np.ndarray, work_width: int, radius: int) -> tuple[np.ndarray, int, float]:
    """(depth at working resolution, disc radius in its pixels, its columns per input column)."""
    import cv2

    h, w = depth.shape
    if w > work_width:
        wh = max(1, round(h * work_width / w))
        return cv2.resize(depth, (work_width, wh), interpolation=cv2.INTER_NEAREST), radius, work_width / w
    # Small maps are used as they are, with the disc scaled to the same fraction of the width.
    return depth, max(1, round(radius * w / work_width)), 1.0


def _valid_u8(depth: np.ndarray):
    """uint8 (H, W): 255 where the depth is finite and positive, else 0 (one multithreaded pass)."""
    import cv2

    return cv2.inRange(depth, float(np.finfo(np.float32).tiny), float(np.finfo(np.float32).max))


def _mask(
    depth_m: np.ndarray, focal_px: float | None, max_angle_deg: float, radius: int, work_width: int
) -> tuple[np.ndarray, np.ndarray]:
    """(edges uint8 (H, W) 0 / 1, valid uint8 (H, W) 0 / nonzero)."""
    import cv2

    depth = np.asarray(depth_m)
    if depth.ndim != 2:
        raise ValueError(f"expected a depth map (H, W), got shape {depth.shape}")
    if not 0.0 < max_angle_deg < 90.0:
        raise ValueError(f"max_angle_deg must lie in (0, 90), got {max_angle_deg}")
    if radius < 1 or work_width < 1:
        raise ValueError("radius and work_width must be positive")
    h, w = depth.shape
    if focal_px is None:
        focal_px = w / (2.0 * math.tan(math.radians(30.0)))
    if not focal_px > 0:
        raise ValueError(f"focal_px must be positive, got {focal_px}")
    depth = depth.astype(np.float32, copy=False)
    small, r, scale = _working_map(depth, work_width, radius)
    valid = np.isfinite(small) & (small > 0)
    log_d = np.log(np.where(valid, small, 1.0), dtype=np.float32)
    kernel = cv2.getStructuringElement(cv2.MORPH_ELLIPSE, (2 * r + 1, 2 * r + 1))
    hi = cv2.dilate(np.where(valid, log_d, -_BIG), kernel, borderType=cv2.BORDER_REPLICATE)
    lo = cv2.erode(np.where(valid, log_d, _BIG), kernel, borderType=cv2.BORDER_REPLICATE)
    # Angular diameter of the disc: 2 r working pixels of focal_px * scale each.
    limit = math.tan(math.radians(max_angle_deg)) * 2.0 * r / (focal_px * scale)
    edges = ((hi - lo > limit) & valid).view(np.uint8)
    if edges.shape == (h, w):
        return edges, valid.view(np.uint8)
    valid_full = _valid_u8(depth)
    edges = cv2.resize(edges, (w, h), interpolation=cv2.INTER_NEAREST)
    return cv2.bitwise_and(edges, valid_full), valid_full


def depth_edge_mask(
    depth_m: np.ndarray,
    focal_px: float | None = None,
    max_angle_deg: float = MAX_ANGLE_DEG,
    radius: int = RADIUS,
    work_width: int = WORK_WIDTH,
) -> np.ndarray:
    """Pixels on a depth discontinuity: bool (H, W), True = flagged (test in the module docstring).

    ``depth_m``: (H, W) depth in metres, 0 / NaN / inf = missing (never flagged). ``focal_px``: the focal
    length in pixels of ``depth_m``'s resolution (e.g. ``sqrt(fx * fy)``); None = a 60 degree horizontal
    field of view. ``max_angle_deg``: the steepest viewing angle (ray to surface normal) a surface may be
    seen at without being flagged. ``radius``: the disc's radius in working pixels, the map subsampled to
    ``work_width`` columns.
    """
    return _mask(depth_m, focal_px, max_angle_deg, radius, work_width)[0].view(bool)


def drop_depth_edges(
    depth_m: np.ndarray,
    focal_px: float | None = None,
    max_angle_deg: float = MAX_ANGLE_DEG,
    radius: int = RADIUS,
    work_width: int = WORK_WIDTH,
) -> tuple[np.ndarray, float]:
    """``depth_m`` with the pixels of :func:`depth_edge_mask` set to 0 (a new array; missing pixels stay as
    they are) and the fraction of the map's valid pixels that were dropped."""
    edges, valid = _mask(depth_m, focal_px, max_angle_deg, radius, work_width)
    out = np.array(depth_m, copy=True)
    np.copyto(out, 0, where=edges.view(bool))
    n_valid = int(np.count_nonzero(valid))
    return out, (float(np.count_nonzero(edges)) / n_valid if n_valid else 0.0)

"""Straight line segments of a photo, for its vanishing points (:mod:`cuboidcli.geometry.vanishing`).

The segments are found on a copy of the image shrunk by an integer factor to at most ``max_side_px`` on its
long side: a vanishing point needs the direction of long edges, not their pixel-exact position, and a
12 MP photo then costs what a 640x480 frame does. Segments come back in the original image's pixels.

Detectors, first available first: OpenCV's LSD (``cv2.createLineSegmentDetector``; von Gioi et al., "LSD:
a fast line segment detector with a false detection control", TPAMI 2010), the fast line detector of
``cv2.ximgproc`` (opencv-contrib builds), else Canny edges and the probabilistic Hough transform
(``cv2.HoughLinesP``), which finds the same long edges, less precisely located.
"""

from __future__ import annotations

import math

import cv2
import numpy as np

#: Long side (pixels) of the copy the segments are found on.
MAX_SIDE_PX = 640

#: Segments shorter than this share of the working image's diagonal are dropped: their direction is too
#: uncertain (one pixel at each end of a 20 px segment is 4 degrees) to vote for a vanishing point.
MIN_LENGTH_FRACTION = 0.03

#: Segments within this share of the short side from an image border and parallel to it are dropped: they
#: are the border of the picture (the black or white frame of registered Kinect images, a letterbox),
#: not an edge of the scene.
BORDER_FRACTION = 0.025


def _shrink(rgb: np.ndarray, max_side_px: int) -> tuple[np.ndarray, int]:
    """(grey working image, integer factor k): the image averaged over k x k blocks (OpenCV's fast path of
    INTER_AREA needs an integer factor, so up to k - 1 rows and columns at the far edges are left out)."""
    h, w = rgb.shape[:2]
    k = max(1, math.ceil(max(h, w) / max_side_px))
    if k > 1:
        hk, wk = h // k * k, w // k * k
        rgb = cv2.resize(rgb[:hk, :wk], (wk // k, hk // k), interpolation=cv2.INTER_AREA)
    grey = rgb if rgb.ndim == 2 else cv2.cvtColor(np.ascontiguousarray(rgb), cv2.COLOR_RGB2GRAY)
    return np.ascontiguousarray(grey), k


def _lsd(grey: np.ndarray) -> np.ndarray | None:
    if not hasattr(cv2, "createLineSegmentDetector"):
        return None
    try:  # some OpenCV 3.4/4.x releases ship the function without the implementation (licence)
        lines = cv2.createLineSegmentDetector().detect(grey)[0]
    except cv2.error:
        return None
    return np.zeros((0, 4)) if lines is None else lines.reshape(-1, 4)


def _fast_line_detector(grey: np.ndarray) -> np.ndarray | None:
    ximgproc = getattr(cv2, "ximgproc", None)
    if ximgproc is None or not hasattr(ximgproc, "createFastLineDetector"):
        return None
    lines = ximgproc.createFastLineDetector().detect(grey)
    return np.zeros((0, 4)) if lines is None else lines.reshape(-1, 4)


def _hough(grey: np.ndarray, min_length_px: float) -> np.ndarray:
    edges = cv2.Canny(cv2.GaussianBlur(grey, (5, 5), 1.0), 50, 150)
    lines = cv2.HoughLinesP(
        edges, 1, np.pi / 720, threshold=max(10, int(min_length_px / 2)),
        minLineLength=min_length_px, maxLineGap=3,
    )  # fmt: skip
    return np.zeros((0, 4)) if lines is None else lines.reshape(-1, 4)


def detect_segments(
    rgb: np.ndarray,
    max_side_px: int = MAX_SIDE_PX,
    min_length_fraction: float = MIN_LENGTH_FRACTION,
) -> np.ndarray:
    """Straight line segments of an image.

    Args:
        rgb: (H, W, 3) uint8 RGB image, or (H, W) uint8 grey.
        max_side_px: the segments are found on a copy shrunk by an integer factor to at most this long side.
        min_length_fraction: segments shorter than this share of the (working) image's diagonal are dropped.

    Returns:
        (N, 4) float64 segments ``x1, y1, x2, y2`` in the original image's pixels (pixel centres at
        integers), longest first; (0, 4) when there are none.
    """
    rgb = np.asarray(rgb)
    if rgb.ndim not in (2, 3) or (rgb.ndim == 3 and rgb.shape[2] != 3) or rgb.dtype != np.uint8:
        raise ValueError(f"expected an (H, W, 3) or (H, W) uint8 image, got {rgb.shape} {rgb.dtype}")
    if min(rgb.shape[:2]) < math.ceil(max(rgb.shape[:2]) / max_side_px):
        return np.zeros((0, 4))  # a sliver of an image: nothing left after shrinking
    grey, k = _shrink(rgb, max_side_px)
    hs, ws = grey.shape
    min_len = min_length_fraction * math.hypot(ws, hs)
    segs = _lsd(grey)
    if segs is None:
        segs = _fast_line_detector(grey)
    if segs is None:
        segs = _hough(grey, min_len)
    segs = segs.astype(np.float64)
    length = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1])
    keep = (length >= min_len) & ~_along_border(segs, ws, hs)
    segs, length = segs[keep], length[keep]
    segs = segs[np.argsort(-length, kind="stable")]
    # a working pixel centre x covers original pixels k x .. k x + k - 1: its centre is k x + (k - 1) / 2
    return segs * k + (k - 1) / 2.0


def _along_border(segs: np.ndarray, width: int, height: int) -> np.ndarray:
    """(N,) whether both ends of a segment lie within the border band of the same image side."""
    margin = BORDER_FRACTION * min(width, height)
    x, y = segs[:, 0::2], segs[:, 1::2]
    return (
        np.all(x < margin, axis=1)
        | np.all(x > width - 1 - margin, axis=1)
        | np.all(y < margin, axis=1)
        | np.all(y > height - 1 - margin, axis=1)
    )

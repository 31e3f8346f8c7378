"""A frame's down direction from its two witnesses: the depth map's surfaces
(:func:`cuboidcli.geometry.gravity.estimate_gravity`) and the photo's lines
(:func:`cuboidcli.geometry.vanishing.estimate_from_lines`), decided by :func:`combine_down`.

- Each estimate is *sure* when its confidence reaches its bar: :data:`LINES_SURE` for the lines'
  ``down_confidence``, :data:`DEPTH_SURE` for the depth's ``confidence``.
- The input says which witness comes first. A photo's depth is predicted by a network, whose surfaces
  put down 36-43 degrees from the true depth's on real NYU photos, while the lines put it within 3.1
  degrees: the lines come first. A depth map is measured: the depth comes first and the lines only
  cross-check it, so a depth map's fit does not change unless its depth-based estimate is unsure.
- The first witness's estimate is used when it is sure, else the other one's when that is sure, else the
  one more confident relative to its bar.
- Both found and within :data:`AGREE_DEG` of each other: the source is "lines and depth" (and the pair
  counts as sure); otherwise "photo lines" or "depth". The down direction and the room's axes are those of
  the estimate used, unchanged.
- Neither sure nor agreeing: a note, the input's one warning about its down direction.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from cuboidcli.geometry.gravity import Gravity
from cuboidcli.geometry.vanishing import LineEstimate

#: The lines' ``down_confidence`` from which their down direction is sure. Measured: 0.69-0.86 on the 11
#: real photos of ../shared/data (all within 3.1 degrees of the true depth's down); below 0.2 on images
#: without a room's lines (random strokes, stripes, noise: tests/geometry/test_vanishing.py).
LINES_SURE = 0.4
#: The depth estimate's ``confidence`` (the share of surface normals along its Manhattan frame) from
#: which it is sure. Measured: 0.23-0.59 on the 7 real depth maps (NYU, TUM); 0.05-0.08 on the depth the
#: built-in network predicts from the same photos (whose down is 36-43 degrees off).
DEPTH_SURE = 0.15
#: Two estimates within this many degrees agree (the lines are within 3.1 degrees of a true depth's).
AGREE_DEG = 10.0

DEPTH, LINES, BOTH = "depth", "photo lines", "lines and depth"


@dataclass(frozen=True)
class DownChoice:
    """The down direction a frame is fitted with, and how sure it is."""

    gravity: Gravity | None
    """The estimate used (its ``source`` says whose), None when neither witness found one."""
    sure: bool
    """The estimate used is sure, or both witnesses agree."""
    note: str = ""
    """When neither is sure (nor do they agree): what each said, in one line; else empty."""


def lines_gravity(lines: LineEstimate, source: str = LINES) -> Gravity:
    """The lines' estimate as a :class:`Gravity`: their down, confidence, room axes and support."""
    return Gravity(
        down=np.asarray(lines.down, dtype=np.float64),
        source=source,
        confidence=float(lines.down_confidence),
        frame=lines.axes,
        support=tuple(float(s) for s in lines.support),
    )


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    """Degrees between two directions."""
    c = float(np.dot(a, b) / (np.linalg.norm(a) * np.linalg.norm(b)))
    return math.degrees(math.acos(min(1.0, max(-1.0, c))))


def combine_down(depth: Gravity | None, lines: LineEstimate | None, lines_first: bool) -> DownChoice:
    """The down direction from the depth's estimate and the lines' (either may be None; lines with a
    zero ``down_confidence`` count as none), ``lines_first`` for a photo (depth predicted from it), as the
    module docstring says."""
    if lines is not None and not lines.down_confidence > 0:
        lines = None
    if depth is None and lines is None:
        return DownChoice(None, False)
    score = {
        DEPTH: -1.0 if depth is None else depth.confidence / DEPTH_SURE,
        LINES: -1.0 if lines is None else lines.down_confidence / LINES_SURE,
    }
    first, second = (LINES, DEPTH) if lines_first else (DEPTH, LINES)
    if score[first] >= 1.0:
        used = first
    elif score[second] >= 1.0:
        used = second
    else:
        used = max((first, second), key=lambda k: score[k])  # ties: the first
    between = None if depth is None or lines is None else angle_deg(depth.down, lines.down)
    agree = between is not None and between <= AGREE_DEG
    source = BOTH if agree else used
    if used == DEPTH:
        gravity = replace(depth, source=source, lines_deg=between)
    else:
        gravity = replace(lines_gravity(lines, source), lines_deg=between)
    sure = agree or score[used] >= 1.0
    note = ""
    if not sure:
        said = [
            f"the photo's lines (confidence {lines.down_confidence:.2f}, sure from {LINES_SURE:g})"
            if lines is not None
            else "the photo's lines (no vanishing points)",
            f"the depth's surfaces (confidence {depth.confidence:.2f}, sure from {DEPTH_SURE:g})"
            if depth is not None
            else "the depth's surfaces (no Manhattan frame)",
        ]
        if between is not None:
            said[-1] += f", {between:.0f} degrees apart"
        note = (
            f"the down direction is uncertain: neither {said[0]} nor {said[1]} fix it; using the "
            f"{'lines' if used == LINES else 'depth'} estimate (boxes may lean; give --gravity gx,gy,gz)"
        )
    return DownChoice(gravity, sure, note)

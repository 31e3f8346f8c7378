"""The camera and the room from a photo's own lines: the down direction, the focal length and the room's
horizontal axes, from the vanishing points of its Manhattan directions.

:func:`estimate_from_lines` finds the image's line segments (:mod:`cuboidcli.geometry.lines`), fits the
three orthogonal scene directions and, when it is not given, the focal length to them
(:mod:`cuboidcli.geometry.manhattan_vp`), and reads off:

- the down direction: the scene direction nearest the image's vertical (its y axis; an ``up_hint`` for
  another), signed to point down. Vertical edges fix it directly, and the horizon (the line through the
  two horizontal vanishing points) fixes it as its normal;
- the focal length: orthogonal directions d1 = K^-1 v1 and d2 = K^-1 v2 give, with the principal point
  c, f^2 = -(v1 - c) . (v2 - c) for two finite vanishing points (fy / fx as given, else 1); with its
  spread (that of the principal point, assumed at the centre, included), and whether the lines, even
  unsure of it, rule out another focal length (a default field of view);
- the room's axes for Manhattan alignment: up and the two horizontal directions, exactly orthogonal.

Each comes with a confidence in [0, 1], 0 meaning "do not use". The image should be upright as displayed
(EXIF orientation applied): the vertical is the scene direction nearest the image's vertical.

Vectors are in the OpenCV camera frame (x right, y down, z forward); pixels have their centres at integers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

import numpy as np

from cuboidcli.geometry.lines import detect_segments
from cuboidcli.geometry.manhattan_vp import ManhattanFit, fit_manhattan

#: The down direction is fully backed when the vertical vanishing point and the weaker horizontal one
#: hold this share of the segments' length between them (the vertical edges fix down, and so does the
#: horizon, which needs both horizontal vanishing points).
DOWN_EVIDENCE = 0.25
#: Standard deviation (degrees) of the down direction, from the refinement's covariance, at which its
#: confidence falls to 1/e.
DOWN_SIGMA_DEG = 1.0
#: The focal length is fully backed when (a) the best frame at a focal length 20 % or more away explains
#: the segments worse by this many segments' worth,
FOCAL_MARGIN = 5.0
#: (b) each of the two vanishing points that fix it holds this share of the segments' length,
FOCAL_EVIDENCE = 0.15
#: and (c) the relative standard deviation of the focal length (from the covariance) is well below this.
FOCAL_SIGMA = 0.035
# The three were chosen on the 11 real photos of ../shared/data and their 480x360 centre crops and on 40
# synthetic rooms and their crops (cuboidcli.synth, the NYU camera), RANSAC seeds 0-3
# (scripts/eval_photo_lines.py --seeds 4 --synth 40): no wrong focal length (more than 10 % off) has more
# than 0.17, the most confident one being the NYU living room's crop, whose sofa edges make a third
# vanishing point at a focal length 31 % short. With (a) at 10, (b) at 0.1 and (c) at 0.05 it had 0.22,
# and fewer right ones reached load.camera.FOCAL_SURE (real full frames 24 of 44 against 27, synthetic
# full frames 115 of 160 against 127, synthetic crops 62 of 160 against 68).

#: Unsure focal lengths can still rule one out (:meth:`LineEstimate.rules_out`, the test of a default
#: field of view): the other focal length is more than RULE_OUT_FACTOR away from the lines' estimate, the
#: lines' best frame there explains the segments at least RULE_OUT_MARGIN segments' worth worse, the
#: estimate's relative standard deviation (:attr:`LineEstimate.focal_sd`) is at most RULE_OUT_SD, and the
#: segments are a room's (:attr:`LineEstimate.coherence` at least RULE_OUT_COHERENCE: random strokes,
#: whose profile has sharp false minima, have 0; every real photo and crop here 1).
RULE_OUT_FACTOR = 1.1
RULE_OUT_MARGIN = 1.0
RULE_OUT_SD = 0.1
RULE_OUT_COHERENCE = 0.5
#: Standard deviation of the true principal point from the image centre, as a share of the long side (the
#: NYU camera's is 14 px below the centre of its 640x480 frames: 2.2 %, 2.9 % of a 480x360 centre crop).
#: The focal length is read with the principal point at the centre; its error moves the focal length
#: most when one of the two vanishing points that fix it is near the centre (a camera facing a wall).
PRINCIPAL_SIGMA = 0.03
# The three were chosen on the 11 real photos of ../shared/data cropped at their centres to 560x420,
# 520x390, 480x360 and 400x300 and off-centre to 480x360 (20 px right and 15 up, and the reverse), and on
# 40 synthetic rooms (the NYU camera) cut the same way, RANSAC seeds 0-1 (scripts/eval_photo_lines.py
# --seeds 2 --synth 40 --crops): the default field of view is kept on every full frame (it is right
# there), and ruled out on 15 of the 22 real 480x360 crops (13 rightly); the test of the spread keeps the
# NYU living room's full frame (facing its wall: the lines' estimate 33 % short and 6.4 segments' worth
# better than the default, but focal_sd 0.20) on the default.

#: Below this share of the segments' length, a vanishing point does not count as seen.
MIN_SUPPORT = 0.02
#: Three directions fitted to N segments with no common structure (random lines, round things) explain
#: up to about CHANCE_BASE + CHANCE_SCALE / sqrt(N) of their length (measured on drawings of random
#: segments: 0.3-0.55 of 40-60 segments, 0.2-0.3 of 100-500): only the support beyond that counts, and
#: both confidences grow from 0 there to full COHERENT_SPAN above it.
CHANCE_BASE = 0.2
CHANCE_SCALE = 1.8
COHERENT_SPAN = 0.2


@dataclass(frozen=True)
class LineEstimate:
    """What a photo's lines say about its camera and its room."""

    down: np.ndarray
    """(3,) unit vector in camera coordinates pointing to the floor."""
    down_confidence: float
    """In [0, 1]: how well the lines fix the down direction."""
    focal_px: float | None
    """fx in pixels from the vanishing points; None when fx was given or the lines cannot fix it (fewer
    than two vanishing points seen)."""
    focal_confidence: float
    """In [0, 1]: how well the lines fix the focal length (0 when ``focal_px`` is None)."""
    axes: np.ndarray
    """(3, 3) the room's Manhattan frame as columns: up (= -down), then two horizontal axes (the better
    supported first), exactly orthogonal and right-handed, as
    :attr:`cuboidcli.geometry.gravity.Gravity.frame`."""
    support: tuple[float, float, float]
    """Share of the segments' length along each column of ``axes``."""
    n_segments: int
    """Line segments found in the image."""
    rms_px: float
    """Root mean square distance (pixels at up to 640 on the long side) of the supporting segments'
    endpoints from the lines to their vanishing points: their angular consistency."""
    fit: ManhattanFit
    """The vanishing-point fit behind it (segment labels, vanishing points, covariance)."""
    focal_sd: float = math.inf
    """Relative standard deviation of ``focal_px``: the fit's, and that of a principal point
    PRINCIPAL_SIGMA of the long side away from the image centre; inf without an estimate."""
    coherence: float = 0.0
    """In [0, 1]: how far the segments' support along the three directions exceeds what random segments
    reach (0 at chance, 1 from COHERENT_SPAN beyond it); both confidences are scaled by it."""

    def focal_worse_at(self, fx: float) -> float:
        """How much worse (segments' worth, the focal prior's cost included) the lines' best frame at focal
        length ``fx`` (pixels) explains the segments than the best the lines found: their likelihood
        profile over the focal length (:attr:`ManhattanFit.profile`), interpolated in log fx. 0 without a
        profile (a given focal length) or outside its range."""
        prof = self.fit.profile
        if len(prof) == 0 or not prof[0, 0] <= fx <= prof[-1, 0]:
            return 0.0
        worse = float(np.interp(math.log(fx), np.log(prof[:, 0]), prof[:, 1]))
        return worse - min(0.0, float(prof[:, 1].min()))

    def rules_out(self, fx: float) -> bool:
        """Whether the lines, sure of their focal length or not, say it is not ``fx`` (pixels): ``fx`` is more
        than RULE_OUT_FACTOR from ``focal_px``, the segments fit a frame at ``fx`` at least RULE_OUT_MARGIN
        segments' worth worse, the estimate's relative spread is at most RULE_OUT_SD, and the segments'
        coherence is at least RULE_OUT_COHERENCE. Used to drop a
        default field of view: an unsure estimate of the lines is then nearer than the default (a cropped
        or zoomed photo)."""
        if self.focal_px is None or not self.focal_sd <= RULE_OUT_SD or self.coherence < RULE_OUT_COHERENCE:
            return False
        if abs(math.log(fx / self.focal_px)) <= math.log(RULE_OUT_FACTOR):
            return False
        return self.focal_worse_at(fx) >= RULE_OUT_MARGIN

    def seen_by(self, fx: float, fy: float, cx: float, cy: float) -> LineEstimate:
        """The estimate in the frame of another camera of the same image (pixels): the vanishing points
        stay where they are in the image, and their directions are those the new intrinsics give them (the
        down direction K'^-1 K d; the horizontal axes made perpendicular to it). Used where the fit's camera
        is not the one the lines were fitted with (a default field of view, a depth model's focal length):
        the down direction must be the vertical edges' direction as that camera back-projects them. The
        confidences and ``focal_px`` (the lines' own estimate) are kept; the same camera: itself."""
        f = self.fit
        (pcx, pcy), pf = f.principal_px, f.focal_px
        old = np.array([[pf, 0.0, pcx], [0.0, f.aspect * pf, pcy], [0.0, 0.0, 1.0]])
        new = np.array([[fx, 0.0, cx], [0.0, fy, cy], [0.0, 0.0, 1.0]], dtype=np.float64)
        if np.allclose(old, new, rtol=1e-9, atol=1e-9):
            return self
        m = np.linalg.solve(new, old)  # K'^-1 K: keeps the sign of each direction (positive diagonals)
        down = m @ self.down
        down /= np.linalg.norm(down)
        h = m @ self.axes[:, 1]
        h -= (h @ down) * down
        h /= np.linalg.norm(h)
        return replace(self, down=down, axes=np.stack([-down, h, np.cross(-down, h)], axis=1))

    def to_dict(self) -> dict:
        """A JSON-ready record (no segment labels)."""
        vps = self.fit.vanishing_points()
        return {
            "down": [round(float(x), 6) for x in self.down],
            "down_confidence": round(float(self.down_confidence), 4),
            "focal_px": None if self.focal_px is None else round(float(self.focal_px), 2),
            "focal_confidence": round(float(self.focal_confidence), 4),
            "focal_sd": None if not math.isfinite(self.focal_sd) else round(float(self.focal_sd), 4),
            "manhattan_frame": [[round(float(x), 6) for x in row] for row in self.axes],
            "support": [round(float(s), 4) for s in self.support],
            "vanishing_points": [[round(float(x), 6) for x in v / np.linalg.norm(v)] for v in vps],
            "n_segments": int(self.n_segments),
            "rms_px": round(float(self.rms_px), 3),
        }


def estimate_from_lines(
    rgb: np.ndarray,
    fx: float | None = None,
    fy: float | None = None,
    cx: float | None = None,
    cy: float | None = None,
    *,
    up_hint: np.ndarray | None = None,
    seed: int = 0,
) -> LineEstimate | None:
    """The down direction, the focal length and the room's axes from an image's lines.

    Args:
        rgb: (H, W, 3) uint8 RGB image, upright (EXIF orientation applied), or (H, W) uint8 grey.
        fx, fy: focal lengths in pixels, when known (fx None: estimated from the lines).
        cx, cy: principal point in pixels; None: the image centre.
        up_hint: (3,) roughly up in camera coordinates, to choose the vertical among the three scene
            directions; None: the image's up, (0, -1, 0).
        seed: seed of the RANSAC sampler (the same seed gives the same estimate).

    Returns:
        The estimate, or None when the image has too few line segments (a plain wall, a blurred photo).
        Raises ValueError only for an image that is not (H, W, 3) or (H, W) uint8, or a bad ``up_hint``.
    """
    rgb = np.asarray(rgb)
    segments = detect_segments(rgb)
    height, width = rgb.shape[:2]
    fit = fit_manhattan(segments, (width, height), fx, fy, cx, cy, seed=seed)
    if fit is None:
        return None
    return line_estimate(fit, len(segments), up_hint=up_hint, focal_given=fx is not None or fy is not None)


def line_estimate(
    fit: ManhattanFit,
    n_segments: int,
    up_hint: np.ndarray | None = None,
    focal_given: bool = False,
) -> LineEstimate:
    """The :class:`LineEstimate` of a vanishing-point fit (see :func:`estimate_from_lines`)."""
    rot = fit.rotation
    hint = np.asarray([0.0, -1.0, 0.0] if up_hint is None else up_hint, dtype=np.float64).reshape(-1)
    if hint.shape != (3,) or not np.all(np.isfinite(hint)) or np.linalg.norm(hint) < 1e-12:
        raise ValueError(f"up_hint must be three finite numbers, not all zero (got {up_hint!r})")
    hint = hint / np.linalg.norm(hint)
    k = int(np.abs(rot.T @ hint).argmax())
    up = rot[:, k] * (1.0 if rot[:, k] @ hint >= 0 else -1.0)
    o1, o2 = sorted((a for a in range(3) if a != k), key=lambda a: -fit.support[a])
    h1 = rot[:, o1] - (rot[:, o1] @ up) * up
    h1 /= np.linalg.norm(h1)
    axes = np.stack([up, h1, np.cross(up, h1)], axis=1)
    support = (float(fit.support[k]), float(fit.support[o1]), float(fit.support[o2]))

    chance = CHANCE_BASE + CHANCE_SCALE / math.sqrt(max(n_segments, 1))
    coherence = min(1.0, max(0.0, (sum(support) - chance) / COHERENT_SPAN))
    # down: the vertical edges and the horizon (both horizontal vanishing points) back it
    evidence = coherence * min(1.0, (support[0] + support[2]) / DOWN_EVIDENCE)
    sd_deg = math.inf
    if np.all(np.isfinite(fit.covariance[:3, :3])):
        p = np.eye(3) - np.outer(up, up)  # a small rotation w moves up by w x up: its part across up
        sd_deg = math.degrees(math.sqrt(max(0.0, float(np.trace(p @ fit.covariance[:3, :3] @ p)))))
    down_conf = evidence * math.exp(-sd_deg / DOWN_SIGMA_DEG)
    if max(support) < MIN_SUPPORT or sum(s >= MIN_SUPPORT for s in support) < 2:
        down_conf = 0.0  # one family of parallel edges leaves a rotation about it free

    focal, focal_conf, focal_sd = None, 0.0, math.inf
    if not focal_given:
        focal, focal_conf = _focal_confidence(fit)
        focal_conf *= coherence
        if focal is not None:
            focal_sd = _focal_spread(fit)
    return LineEstimate(
        down=-up,
        down_confidence=float(down_conf),
        focal_px=focal,
        focal_confidence=float(focal_conf),
        axes=axes,
        support=support,
        n_segments=int(n_segments),
        rms_px=fit.rms_px,
        fit=fit,
        focal_sd=focal_sd,
        coherence=float(coherence),
    )


def _focal_confidence(fit: ManhattanFit) -> tuple[float | None, float]:
    """(fx or None, confidence) of a fit with a free focal length.

    The focal length is fixed by the two vanishing points nearest the principal point (a far one only
    says where the others lie): both must be seen, and the weaker one's support, the margin over rival
    focal lengths and the covariance's relative standard deviation each scale the confidence.
    """
    # distance of each vanishing point from the principal point in focal lengths: tan of its angle
    # to the optical axis, through the rotation (no division by a vanishing point at infinity)
    rot = fit.rotation
    tan = np.hypot(rot[0], rot[1]) / np.maximum(np.abs(rot[2]), 1e-12)
    pair = np.argsort(tan)[:2]
    weaker = float(fit.support[pair].min())
    sd = math.sqrt(fit.covariance[3, 3]) if np.isfinite(fit.covariance[3, 3]) else math.inf
    if weaker < MIN_SUPPORT or not math.isfinite(sd):
        return None, 0.0
    conf = (
        min(1.0, max(0.0, fit.focal_margin) / FOCAL_MARGIN)
        * min(1.0, weaker / FOCAL_EVIDENCE)
        * math.exp(-sd / FOCAL_SIGMA)
    )
    return float(fit.focal_px), conf


def _focal_spread(fit: ManhattanFit) -> float:
    """Relative standard deviation of a fit's focal length: the refinement's, and that of the principal
    point (PRINCIPAL_SIGMA of the long side in each direction) carried through f^2 = -(v1 - c).(v2 - c) for
    the two vanishing points nearest the centre: moving c by dc moves f^2 by -(v1 - c + v2 - c).dc, so
    log f by (a1 + a2).dc / (2 f) with a_k = (v_k - c) / f, each vanishing point's offset in focal lengths."""
    rot = fit.rotation
    tan = np.hypot(rot[0], rot[1]) / np.maximum(np.abs(rot[2]), 1e-12)
    pair = np.argsort(tan)[:2]
    if np.any(np.abs(rot[2, pair]) < 1e-12):
        return math.inf
    offsets = rot[:2, pair] / rot[2, pair]  # (2, 2) columns a_k
    sigma_c = PRINCIPAL_SIGMA * max(fit.size)
    principal = float(np.linalg.norm(offsets.sum(axis=1))) / 2 * sigma_c / fit.focal_px
    own = math.sqrt(fit.covariance[3, 3]) if np.isfinite(fit.covariance[3, 3]) else math.inf
    return math.hypot(own, principal)

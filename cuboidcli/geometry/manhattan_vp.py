"""The Manhattan frame of an image's line segments, and the focal length, by RANSAC.

Indoor scenes are full of straight edges along three orthogonal directions (walls meet along verticals,
floors and ceilings along two horizontals). The images of the edges along one direction d meet in that
direction's vanishing point v ~ K d. A rotation R whose columns are the three directions, and the focal
length f of K when it is not given, are estimated from the segments:

- hypotheses: the 3-line minimal solver at a known focal length. Two segments give d1, the common
  direction of their interpretation planes (the planes through the camera centre and a segment, normal
  K^T l); a third gives d2, perpendicular to d1 and in its plane; d3 = d1 x d2. This is the minimal case
  of Lu et al., "2-line exhaustive searching for real-time vanishing point estimation in Manhattan
  world", WACV 2017, drawn at random (segments by length) instead of searched exhaustively;
- score: MSAC over the segments with the endpoint-distance residual of :mod:`cuboidcli.geometry.vp_model`,
  each segment weighted by its length;
- refinement: Gauss-Newton with Huber weights on the same residuals, over R and, with a free focal
  length, log f (:func:`cuboidcli.geometry.vp_model.refine_frames`).

With the focal length unknown, orthogonality ties it to the vanishing points: two finite ones v1, v2 give
f^2 = -(v1 - c) . (v2 - c) with c the principal point (Caprile and Torre, "Using vanishing points for
camera calibration", IJCV 1990). It is searched as a profile, because the cost is multimodal in f (which
segments fit which vanishing point changes with it): the best frame is found and refined at each focal
length of a log-spaced grid, from the best frames drawn at every focal length of the grid, and the grid's
best local minima start the joint refinement. The profile also says how sure the estimate is: a frame at
a focal length 20 % away that explains the segments about as well makes f ambiguous; f is not observable
at all when fewer than two vanishing points are finite (a camera facing a wall squarely, level). The fit
keeps a finer likelihood profile (:attr:`ManhattanFit.profile`, the best frame refined on all segments at
each of LIKELIHOOD_STEPS focal lengths), from which an unsure estimate can still rule a focal length out
(:meth:`cuboidcli.geometry.vanishing.LineEstimate.rules_out`).

Vectors are in the OpenCV camera frame (x right, y down, z forward); pixels have their centres at integers.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field

import numpy as np

from cuboidcli.geometry.vp_model import (
    Segments,
    frame_covariance,
    msac_cost,
    refine_frames,
    residuals,
    vanishing_points,
)

#: MSAC threshold: a segment supports a vanishing point when its endpoints are within this many pixels
#: (of an image of at most 640 pixels on its long side, as the segments are found) of the line through its
#: midpoint and the vanishing point.
INLIER_PX = 1.5
#: Fewer segments than this: no estimate.
MIN_SEGMENTS = 12
#: The segments scored per hypothesis: the longest this many (all of them in the refinement).
SCORED_SEGMENTS = 250
#: Focal lengths searched when none is given, as fields of view of the image's long side (degrees).
FOV_RANGE_DEG = (25.0, 120.0)
#: Focal lengths of the profile (log-spaced over FOV_RANGE_DEG).
PROFILE_STEPS = 14
#: Frames kept from each focal length's hypotheses as candidates for all focal lengths of the profile,
PROFILE_CANDIDATES = 3
#: and the best candidates at each focal length refined there.
PROFILE_REFINED = 3
#: A weak prior on the focal length, for when the lines leave it ambiguous (a second vanishing point
#: backed by few segments, a frame with one far rival): its cost is PRIOR_WEIGHT segments' worth times
#: ((log f - log f0) / PRIOR_SIGMA)^2, f0 the focal length of a PRIOR_FOV_DEG field of view on the
#: long side (that of most phones and of Kinect-like cameras). Without it, the nearly affine frames of
#: long focal lengths win on crops: with three vanishing points far out they explain any three families
#: of nearly parallel segments.
PRIOR_WEIGHT = 2.0
PRIOR_FOV_DEG = 60.0
PRIOR_SIGMA = 0.35
#: A rival frame at a focal length at least this factor away decides the focal length's ambiguity.
RIVAL_FACTOR = 1.2
#: Focal lengths of the likelihood profile (log-spaced over FOV_RANGE_DEG, about 4.4 % apart): the best
#: frame at each, refined on all segments, says how much worse the segments fit there.
LIKELIHOOD_STEPS = 48


@dataclass(frozen=True)
class ManhattanFit:
    """Three orthogonal scene directions and the focal length that explain an image's segments."""

    rotation: np.ndarray
    """(3, 3) the directions as columns, camera coordinates (their order and signs are arbitrary)."""
    focal_px: float
    """fx in pixels (estimated, or the one given)."""
    aspect: float
    """fy / fx."""
    principal_px: tuple[float, float]
    """(cx, cy) in pixels."""
    labels: np.ndarray
    """(N,) int: the column of ``rotation`` each segment (as given) supports, -1 for none."""
    support: np.ndarray
    """(3,) share of the segments' total length that supports each column."""
    rms_px: float
    """Root mean square residual of the supporting segments, in pixels of the image scaled to at most
    640 on its long side (as the segments are found)."""
    covariance: np.ndarray
    """(4, 4) covariance of the refinement's parameters: a small rotation (3, radians, applied on the
    left) and log fx (zero row and column when fx was given)."""
    focal_margin: float
    """How much worse the best frame at a focal length RIVAL_FACTOR or more away explains the segments, in
    segments' worth (segment lengths relative to their mean); 0 when fx was given."""
    size: tuple[int, int] = (0, 0)
    """(width, height) of the image in pixels."""
    profile: np.ndarray = field(default_factory=lambda: np.zeros((0, 2)))
    """(K, 2) the likelihood profile of the focal length: fx in pixels and how much worse (segments' worth,
    the prior's cost included) the best frame at that fx explains the segments than the fit; (0, 2) when
    fx was given."""

    def vanishing_points(self) -> np.ndarray:
        """(3, 3) homogeneous pixel coordinates of the vanishing points (rows), last coordinate 0 at
        infinity."""
        (cx, cy), f = self.principal_px, self.focal_px
        k = np.array([[f, 0, cx], [0, self.aspect * f, cy], [0, 0, 1.0]])
        return (k @ self.rotation).T


def _unit(v: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    n = np.linalg.norm(v, axis=-1, keepdims=True)
    return v / np.maximum(n, 1e-300), n[..., 0]


def _hypotheses(lines: Segments, rng, phis: np.ndarray, aspect: float) -> tuple[np.ndarray, np.ndarray]:
    """Frames (M, 3, 3) from 3 segments each at the focal lengths phis (M,), and which are valid (M,)."""
    p = lines.weight / lines.weight.sum()
    idx = rng.choice(len(p), size=(len(phis), 3), p=p)
    n = lines.line[idx] * np.stack([phis, aspect * phis, np.ones_like(phis)], -1)[:, None]  # K^T l
    d1, n1 = _unit(np.cross(n[:, 0], n[:, 1]))
    d2, n2 = _unit(np.cross(d1, n[:, 2]))
    ok = (n1 > 1e-9) & (n2 > 1e-9)  # a repeated segment or two parallel planes define no direction
    return np.stack([d1, d2, np.cross(d1, d2)], axis=-1), ok


def _focal_profile(scored: Segments, rng, hypotheses: int, aspect: float, thr: float, phi_range):
    """The best frame at each focal length of a log-spaced grid: (phis (J,), rotations (J, 3, 3),
    costs (J,) with the prior's).

    Hypotheses drawn at one focal length find the frames its segments suggest there; the right frame
    may be drawn only at another one (its three segments fit together only near there). So the best
    few frames of every focal length are candidates at all of them: each focal length's best candidates
    are refined at it, and the profile is the lower envelope of what all focal lengths found, not a
    per-focal-length draw (whose noise made false minima and hid true ones). A candidate keeps its
    directions (its vanishing points move with the focal length; moving them back by a rotation is
    impossible, the nearest rotation to K'^-1 K R being R itself), and the refinement takes it from there.
    """
    grid = np.geomspace(phi_range[0], phi_range[1], PROFILE_STEPS)
    per = max(2, hypotheses // len(grid))
    phis = np.repeat(grid, per)
    rots, ok = _hypotheses(scored, rng, phis, aspect)
    cost = np.where(ok, msac_cost(rots, phis, scored, aspect, thr), np.inf)
    cand = []
    for j in range(len(grid)):
        sl = slice(j * per, (j + 1) * per)
        cand += [rots[sl][i] for i in _distinct_best(rots[sl], cost[sl], PROFILE_CANDIDATES)]
    if not cand:
        return grid[:0], np.zeros((0, 3, 3)), np.zeros(0)
    cand = np.stack(cand)
    tried = np.broadcast_to(cand, (len(grid),) + cand.shape)  # (J, C, 3, 3): every candidate everywhere
    at = np.broadcast_to(grid[:, None], tried.shape[:2])
    first = msac_cost(tried, at, scored, aspect, thr)
    keep = np.argsort(first, axis=1)[:, :PROFILE_REFINED]  # (J, k)
    starts = np.take_along_axis(tried, keep[..., None, None], axis=1).reshape(-1, 3, 3)
    start_phis = np.repeat(grid, keep.shape[1])
    refined, _ = refine_frames(starts, start_phis, scored, aspect, thr, False, phi_range, steps=4)
    costs = msac_cost(refined, start_phis, scored, aspect, thr).reshape(len(grid), -1)
    best = costs.argmin(1)
    rots_best = refined.reshape(len(grid), -1, 3, 3)[np.arange(len(grid)), best]
    return grid, rots_best, costs[np.arange(len(grid)), best] + _prior(grid, thr)


def _prior(phi, thr):
    """The focal-length prior's cost (in the units of :func:`msac_cost`) at phi (...,)."""
    phi0 = 0.5 / math.tan(math.radians(PRIOR_FOV_DEG) / 2)
    return PRIOR_WEIGHT * thr**2 * (np.log(np.asarray(phi) / phi0) / PRIOR_SIGMA) ** 2


def _profile_starts(grid, rots, costs) -> list[tuple[np.ndarray, float]]:
    """Starts of the joint refinement: the profile's two best local minima, each moved to the minimum of
    the parabola through its neighbours' costs (in log phi)."""
    n = len(grid)
    minima = [j for j in range(n) if costs[j] <= min(costs[max(j - 1, 0)], costs[min(j + 1, n - 1)])]
    starts = []
    for j in sorted(minima, key=lambda j: costs[j])[:2]:
        log_phi = math.log(grid[j])
        if 0 < j < n - 1:
            c0, c1, c2 = costs[j - 1 : j + 2]
            if c0 - 2 * c1 + c2 > 0:
                log_phi += 0.5 * (c0 - c2) / (c0 - 2 * c1 + c2) * math.log(grid[j + 1] / grid[j])
        starts.append((rots[j], math.exp(log_phi)))
    return starts


def fit_manhattan(
    segments: np.ndarray,
    size: tuple[int, int],
    fx: float | None = None,
    fy: float | None = None,
    cx: float | None = None,
    cy: float | None = None,
    seed: int = 0,
    hypotheses: int = 840,
) -> ManhattanFit | None:
    """The Manhattan frame (and the focal length, when ``fx`` is None) that best explains the segments.

    Args:
        segments: (N, 4) segments ``x1, y1, x2, y2`` in pixels
            (:func:`cuboidcli.geometry.lines.detect_segments`); the longest SCORED_SEGMENTS score the
            hypotheses, all of them the refinement.
        size: (width, height) of the image in pixels.
        fx, fy: focal lengths in pixels; fx None: estimated, with fy = fx (when only fy is given, fx = fy).
        cx, cy: principal point in pixels; None: the image centre.
        seed: seed of the RANSAC sampler (the same seed gives the same fit).
        hypotheses: RANSAC hypotheses drawn (over all focal lengths of the profile when fx is None).

    Returns:
        The fit, or None when there are fewer than MIN_SEGMENTS segments.
    """
    segments = np.asarray(segments, dtype=np.float64).reshape(-1, 4)
    length = np.hypot(segments[:, 2] - segments[:, 0], segments[:, 3] - segments[:, 1])
    usable = np.flatnonzero(np.isfinite(length) & (length > 1e-6))
    order = usable[np.argsort(-length[usable], kind="stable")]  # longest first: they score hypotheses
    width, height = size
    if len(order) < MIN_SEGMENTS:
        return None
    scale = float(max(width, height))
    cx = (width - 1) / 2.0 if cx is None else float(cx)
    cy = (height - 1) / 2.0 if cy is None else float(cy)
    if fx is None and fy is not None:
        fx = fy
    aspect = 1.0 if fx is None or fy is None else float(fy) / float(fx)
    lines = Segments(segments[order], cx, cy, scale)
    scored = lines.take(slice(SCORED_SEGMENTS))
    work_px = min(scale, 640.0)  # pixels of the image the segments were found on
    thr = INLIER_PX / work_px
    phi_range = tuple(0.5 / math.tan(math.radians(a) / 2) for a in FOV_RANGE_DEG[::-1])
    rng = np.random.default_rng(seed)
    free = fx is None
    if free:
        grid, prof_rots, prof_costs = _focal_profile(scored, rng, hypotheses, aspect, thr, phi_range)
        starts = _profile_starts(grid, prof_rots, prof_costs)
    else:
        phis = np.full(hypotheses, float(fx) / scale)
        rots, ok = _hypotheses(scored, rng, phis, aspect)
        cost = np.where(ok, msac_cost(rots, phis, scored, aspect, thr), np.inf)
        starts = [(rots[i], phis[0]) for i in _distinct_best(rots, cost, 3)]
    if not starts:
        return None
    start_rots, start_phis = np.stack([s[0] for s in starts]), np.array([s[1] for s in starts])
    rots, phis = refine_frames(start_rots, start_phis, lines, aspect, thr, free, phi_range)
    costs = msac_cost(rots, phis, lines, aspect, thr) + (_prior(phis, thr) if free else 0.0)
    i = int(costs.argmin())
    rot, phi = rots[i], float(phis[i])
    margin, profile = 0.0, np.zeros((0, 2))
    if free:  # the best frame at a focal length RIVAL_FACTOR or more away, refined on all segments
        far = np.abs(np.log(grid / phi)) >= math.log(RIVAL_FACTOR)
        if far.any():
            rival_rots, _ = refine_frames(
                prof_rots[far], grid[far], lines, aspect, thr, False, phi_range, steps=4
            )
            rival = (msac_cost(rival_rots, grid[far], lines, aspect, thr) + _prior(grid[far], thr)).min()
            margin = float(rival - costs[i]) / thr**2
        else:
            margin = math.inf
        fine, fine_costs = _likelihood_profile(
            np.concatenate([prof_rots, rot[None]]), lines, aspect, thr, phi_range
        )
        profile = np.stack([fine * scale, (fine_costs - costs[i]) / thr**2], axis=1)
    res = np.abs(residuals(vanishing_points(rot, phi, aspect), lines))
    lab, rmin = res.argmin(axis=0), res.min(axis=0)
    lab[rmin >= thr] = -1
    labels = np.full(len(segments), -1)
    labels[order] = lab
    w, sel = lines.weight, lab >= 0
    return ManhattanFit(
        rotation=rot,
        focal_px=phi * scale,
        aspect=aspect,
        principal_px=(cx, cy),
        labels=labels,
        support=np.array([w[lab == k].sum() for k in range(3)]) / w.sum(),
        rms_px=float(np.sqrt(np.mean(rmin[sel] ** 2)) * work_px) if sel.any() else math.inf,
        covariance=frame_covariance(rot, phi, lines, aspect, thr, free),
        focal_margin=margin,
        size=(int(width), int(height)),
        profile=profile,
    )


def _likelihood_profile(cands: np.ndarray, lines: Segments, aspect: float, thr: float, phi_range):
    """(phis (K,), costs (K,) with the prior's) of the best frame at each of LIKELIHOOD_STEPS focal
    lengths: the candidate frames (C, 3, 3) are scored at each on all segments, and the best two are
    refined there (the focal length held)."""
    fine = np.geomspace(phi_range[0], phi_range[1], LIKELIHOOD_STEPS)
    at = np.broadcast_to(fine[:, None], (len(fine), len(cands)))
    first = msac_cost(np.broadcast_to(cands, at.shape + (3, 3)), at, lines, aspect, thr)
    keep = np.argsort(first, axis=1)[:, :2]
    starts = cands[keep].reshape(-1, 3, 3)
    phis = np.repeat(fine, keep.shape[1])
    refined, _ = refine_frames(starts, phis, lines, aspect, thr, False, phi_range, steps=4)
    cost = msac_cost(refined, phis, lines, aspect, thr).reshape(len(fine), -1).min(axis=1)
    return fine, cost + _prior(fine, thr)


def _distinct_best(rots: np.ndarray, cost: np.ndarray, k: int, min_deg: float = 5.0) -> list[int]:
    """Indices of the k lowest-cost frames that differ by more than min_deg (as sets of axes)."""
    out: list[int] = []
    cos_t = math.cos(math.radians(min_deg))
    for i in np.argsort(cost):
        if not np.isfinite(cost[i]):
            break
        if not any(np.all(np.abs(rots[i].T @ rots[j]).max(axis=1) > cos_t) for j in out):
            out.append(int(i))
        if len(out) == k:
            break
    return out

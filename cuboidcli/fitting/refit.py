"""A box's faces moved onto the points it explains (numpy, float64): the extents of a box turned to new
axes (:func:`refit_box`), and the plane most of a slab's points lie on (:func:`plane_sweep`). Squaring a
slab (:mod:`cuboidcli.fitting.winner`) and aligning a winner (:mod:`cuboidcli.fitting.align`) use both."""

from __future__ import annotations

import numpy as np

from cuboidcli.fitting.box import ROBUST_PERCENTILES, thin_axis
from cuboidcli.geometry.inlier import INLIER_CUT

FACE_BAND_M = 0.06
"""A point lies on a face plane of a box when it is this close to it (m); about sqrt(tau)."""
FACE_MIN_POINTS = 5
"""A face moves onto its points from this many points on."""
SWEEP_STEP_M = 0.01
"""Step of the plane positions :func:`plane_sweep` tries (m)."""


def refit_box(p: np.ndarray, center: np.ndarray, half: np.ndarray, rot: np.ndarray, a_min: float):
    """The box of the given half-sizes and centre turned to axes ``rot``, with its faces moved onto the
    points p (M, 3) it explains: a point lies on the face plane nearest to it when it is within
    :data:`FACE_BAND_M` of it, and a face with points moves to their median; faces without points stay
    (growing moves them). A slab keeps its thickness, the face its points lie on goes to their median,
    and it spans their :data:`~cuboidcli.fitting.box.ROBUST_PERCENTILES` along its two long axes.
    Returns (center (3,), half (3,))."""
    local = (p - center) @ rot
    half = half.copy()
    slab = thin_axis(half)
    # distance of every point to each face plane, faces ordered (+x, -x, +y, -y, +z, -z): (M, 6)
    dist = np.abs(local[:, :, None] - np.stack([half, -half], axis=1)[None]).reshape(len(p), 6)
    nearest = dist.argmin(1)
    on_face = dist.min(1) < FACE_BAND_M
    lo, hi = -half.copy(), half.copy()
    mid = np.zeros(3)
    for k in range(3):
        if k == slab:  # the face the points lie on moves onto their median; the thickness stays behind it
            med = float(np.median(local[:, k]))
            mid[k] = med - np.sign(med) * half[k]
            continue
        if slab >= 0:  # a slab's edges have no points on them: it ends where its points end
            lo[k], hi[k] = np.percentile(local[:, k], ROBUST_PERCENTILES)
            mid[k], half[k] = 0.5 * (lo[k] + hi[k]), 0.5 * (hi[k] - lo[k])
            continue
        for side, bound in ((0, hi), (1, lo)):
            sel = on_face & (nearest == 2 * k + side)
            if sel.sum() >= FACE_MIN_POINTS:
                bound[k] = np.median(local[sel, k])
        if hi[k] - lo[k] < 2 * a_min:
            lo[k], hi[k] = -half[k], half[k]
        mid[k] = 0.5 * (lo[k] + hi[k])
        half[k] = 0.5 * (hi[k] - lo[k])
    return center + rot @ mid, np.maximum(half, a_min)


def plane_sweep(
    points: np.ndarray, state: np.ndarray, own: np.ndarray, rot: np.ndarray, k: int
) -> np.ndarray:
    """The points of the best plane with normal ``rot[:, k]`` near a slab's own points ``own`` (M, 3): over
    the not yet explained points in the slab's footprint (its in-plane extent,
    :data:`~cuboidcli.fitting.box.ROBUST_PERCENTILES`) and within its depth range along the normal, the
    plane position holding the most points within :data:`FACE_BAND_M`, in :data:`SWEEP_STEP_M` steps. A
    wall measured with a tilt (bent far depth) then stands where most of its points are, instead of at their
    median."""
    n = rot[:, k]
    i, j = [m for m in range(3) if m != k]
    s_own = own @ n
    lo, hi = np.percentile(s_own, ROBUST_PERCENTILES)
    uv_own = own @ rot[:, [i, j]]
    uv_lo, uv_hi = np.percentile(uv_own, ROBUST_PERCENTILES, axis=0)
    uv = points @ rot[:, [i, j]]
    sp = points @ n
    sel = (
        (state < INLIER_CUT)
        & (state >= 0.0)
        & np.all((uv >= uv_lo) & (uv <= uv_hi), axis=1)
        & (sp >= lo - FACE_BAND_M)
        & (sp <= hi + FACE_BAND_M)
    )
    cand, sv = points[sel], np.sort(sp[sel])
    if sv.size == 0:
        return own
    offsets = np.arange(lo, hi + 0.5 * SWEEP_STEP_M, SWEEP_STEP_M)
    counts = np.searchsorted(sv, offsets + FACE_BAND_M) - np.searchsorted(sv, offsets - FACE_BAND_M)
    best = offsets[int(np.argmax(counts))]
    return cand[np.abs(sp[sel] - best) < FACE_BAND_M]

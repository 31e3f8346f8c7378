"""Fused CPU scoring of cuboid hypotheses: the inlier-count gain of every hypothesis in one pass.

For hypothesis h and state values s(y) = f_OAI(y, M) of the cuboids selected so far, the gain is
    I_i(h) = sum_y [ combine(f_OAI(y, {h}), s(y)) - s(y) ]          (paper Eq. 9-10, Sec. 3.5)
computed without materialising (H, N, 6, 3) tensors (the research code's 8.7 GB): each pair's value comes
from :func:`cuboidcli.geometry.inlier.pair_value` (why that is cheap is said there), points too far from a
box and outside its silhouette are skipped (:func:`_screen`), a hypothesis that cannot reach the threshold
is abandoned early, and on an image grid (:mod:`.cells`) a hypothesis visits only the cells it can reach.
Tested against the torch reference kernels in :mod:`cuboidcli.geometry.kernels`.

The scorer (:mod:`cuboidcli.fitting.backend`) and assignment call the loops here; :func:`cuboid_values`
gives each cuboid's values on its own.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from numba import njit, prange

from cuboidcli.geometry.cells import ImageCells, box_sum, grid_reach
from cuboidcli.geometry.inlier import camera_local, inlier_params, pair_value, to_local


@njit(cache=True)
def _screen(t0, t1, t2, a0, a1, a2, R, cutoff):
    """Per-hypothesis bounds for skipping pairs that cannot contribute.

    Returns (r2, u_lo, u_hi, v_lo, v_hi): a point farther than sqrt(r2) from the centre has d^2 >= cutoff;
    a point whose normalised image coordinates (x/z, y/z) lie outside [u_lo, u_hi] x [v_lo, v_hi] cannot be
    occluded, since its line of sight misses the box's projection (infinite when the box reaches z <= 0).
    """
    rad = math.sqrt(a0 * a0 + a1 * a1 + a2 * a2) + math.sqrt(cutoff)
    u_lo = 1e300
    u_hi = -1e300
    v_lo = 1e300
    v_hi = -1e300
    for k in range(8):
        s0 = a0 if k & 1 else -a0
        s1 = a1 if k & 2 else -a1
        s2 = a2 if k & 4 else -a2
        x = t0 + R[0, 0] * s0 + R[0, 1] * s1 + R[0, 2] * s2
        y = t1 + R[1, 0] * s0 + R[1, 1] * s1 + R[1, 2] * s2
        z = t2 + R[2, 0] * s0 + R[2, 1] * s1 + R[2, 2] * s2
        if z <= 1e-6:
            return rad * rad, -1e300, 1e300, -1e300, 1e300
        u_lo = min(u_lo, x / z)
        u_hi = max(u_hi, x / z)
        v_lo = min(v_lo, y / z)
        v_hi = max(v_hi, y / z)
    eps = 1e-9
    return rad * rad, u_lo - eps, u_hi + eps, v_lo - eps, v_hi + eps


@njit(cache=True, inline="always")
def _box_of(centers, half, rot, h, cutoff):
    """Hypothesis h as the scoring loops use it: (t0, t1, t2, a0, a1, a2, R, c0, c1, c2, screen) with the
    camera c in its frame and ``screen`` = (r2, u_lo, u_hi, v_lo, v_hi) of :func:`_screen`."""
    t0, t1, t2 = centers[h, 0], centers[h, 1], centers[h, 2]
    a0, a1, a2 = half[h, 0], half[h, 1], half[h, 2]
    R = rot[h]
    c0, c1, c2 = camera_local(t0, t1, t2, R)
    return t0, t1, t2, a0, a1, a2, R, c0, c1, c2, _screen(t0, t1, t2, a0, a1, a2, R, cutoff)


@njit(cache=True, inline="always")
def _accumulate(points, uv, lo, hi, old, box, params, acc):
    """acc plus the gain contributions of points lo..hi-1 (in order) for one hypothesis (``box`` of
    :func:`_box_of`): sum of combine(f_OAI(y, {h}), s(y)) - s(y); ``params`` = (beta, 1/tau, tau_c, slope,
    offset, cutoff, oai)."""
    t0, t1, t2, a0, a1, a2, R, c0, c1, c2, screen = box
    r2, u_lo, u_hi, v_lo, v_hi = screen
    beta, inv_tau, tau_c, slope, offset, cutoff, oai = params
    for i in range(lo, hi):
        x = points[i, 0] - t0
        y = points[i, 1] - t1
        z = points[i, 2] - t2
        near = x * x + y * y + z * z < r2
        if not near:
            if not oai:
                continue
            u = uv[i, 0]
            v = uv[i, 1]
            if u < u_lo or u > u_hi or v < v_lo or v > v_hi:
                continue  # value 0 and combine(0, s) = s: no contribution
        l0, l1, l2 = to_local(x, y, z, R)
        v = pair_value(l0, l1, l2, a0, a1, a2, c0, c1, c2, beta, inv_tau, tau_c, slope, offset, cutoff, oai)
        o = old[i]
        lo_v = min(v, o)
        acc += (lo_v if lo_v < 0 else max(v, o)) - o
    return acc


@njit(parallel=True, cache=True)
def _gains(points, uv, centers, half, rot, old, ub_suffix, threshold, params, out):
    n = points.shape[0]
    cutoff = params[5]
    for h in prange(centers.shape[0]):
        box = _box_of(centers, half, rot, h, cutoff)
        acc = 0.0
        pruned = False
        for lo in range(0, n, 64):
            if acc + ub_suffix[lo] < threshold:
                pruned = True  # cannot reach the threshold even if every remaining point became an inlier
                break
            hi = min(lo + 64, n)
            acc = _accumulate(points, uv, lo, hi, old, box, params, acc)
        out[h] = -np.inf if pruned else acc


@njit(parallel=True, cache=True)
def _gains_cells(
    points, uv, cell_start, col_u, row_v, ub_sat, centers, half, rot, old, threshold, params, out
):
    """:func:`_gains` over the points of an image grid, each hypothesis visiting only the rows and columns
    its near zone and its silhouette can reach (every other point adds exactly 0), in the points' order."""
    cols = col_u.shape[0]
    cutoff = params[5]
    for h in prange(centers.shape[0]):
        box = _box_of(centers, half, rot, h, cutoff)
        # the near zone (r2) holds the box, so the cube around the sphere of radius sqrt(r2) holds both
        r_lo, r_hi, k_lo, k_hi = grid_reach(box[0], box[1], box[2], math.sqrt(box[10][0]), col_u, row_v)
        acc = 0.0
        pruned = False
        for r in range(r_lo, r_hi + 1):
            # slack: the table's rounding must never prune a hypothesis that reaches the threshold
            if acc + box_sum(ub_sat, cols, r, r_hi, k_lo, k_hi) + 1e-7 < threshold:
                pruned = True
                break
            lo = cell_start[r * cols + k_lo]
            hi = cell_start[r * cols + k_hi + 1]
            acc = _accumulate(points, uv, lo, hi, old, box, params, acc)
        out[h] = -np.inf if pruned else acc


def _f64(*arrays) -> list[np.ndarray]:
    return [np.ascontiguousarray(a, np.float64) for a in arrays]


@dataclass(frozen=True)
class ScoringArrays:
    """What scoring hypotheses against one set of points and one state needs, computed once
    (:func:`scoring_arrays`) and reused by every batch and every single box scored against them."""

    points: np.ndarray  # (N, 3) float64
    uv: np.ndarray  # (N, 2) x/z, y/z
    state: np.ndarray  # (N,) float64
    bound: np.ndarray  # cells: summed-area table of the per-point gain bound; else its suffix sums (N + 1,)
    cells: ImageCells | None = None


def scoring_arrays(points, state, cells: ImageCells | None = None) -> ScoringArrays:
    """:class:`ScoringArrays` of points (N, 3) and state (N,) (numpy, any float dtype); ``cells`` as in
    :func:`score_gains`."""
    points, state = _f64(points, state)
    with np.errstate(divide="ignore", invalid="ignore"):
        uv = np.ascontiguousarray(points[:, :2] / points[:, 2:3])
    # a point adds at most max(0, 1 - s) (values are <= 1), and nothing when s < 0
    ub = np.where(state < 0, 0.0, np.maximum(0.0, 1.0 - state))
    if cells is not None:
        if cells.start[-1] != points.shape[0]:
            raise ValueError(f"the cells hold {cells.start[-1]} points, not {points.shape[0]}")
        return ScoringArrays(points, uv, state, cells.summed_area(ub), cells)
    return ScoringArrays(points, uv, state, np.concatenate([np.cumsum(ub[::-1])[::-1], [0.0]]))


def gains_of(
    arrays: ScoringArrays, centers, half_sizes, rotations, params: tuple, prune_below: float = -np.inf
) -> np.ndarray:
    """:func:`score_gains` on prepared :class:`ScoringArrays`; ``params`` = :func:`inlier_params`."""
    out = np.empty(centers.shape[0], dtype=np.float64)
    centers, half_sizes, rotations = _f64(centers, half_sizes, rotations)
    a = arrays
    if a.cells is not None:
        c = a.cells
        _gains_cells(
            a.points, a.uv, c.start, c.col_u, c.row_v, a.bound, centers, half_sizes, rotations, a.state,
            float(prune_below), params, out,
        )  # fmt: skip
    else:
        thr = float(prune_below)
        _gains(a.points, a.uv, centers, half_sizes, rotations, a.state, a.bound, thr, params, out)
    return out


def score_gains(
    points,
    centers,
    half_sizes,
    rotations,
    state,
    tau: float,
    beta: float,
    tau_c: float,
    occlusion_aware: bool = True,
    prune_below: float = -np.inf,
    cells: ImageCells | None = None,
) -> np.ndarray:
    """Inlier-count gain of each hypothesis over the current state.

    points (N, 3), centers (H, 3), half_sizes (H, 3), rotations (H, 3, 3), state (N,) = f_OAI of the
    selected set (zeros when empty); numpy arrays, float32 or float64. Returns (H,) float64.

    ``prune_below``: hypotheses whose gain provably stays below it are abandoned early and reported as
    -inf. A point can add at most max(0, 1 - s(y)) (values are <= 1, and nothing when s(y) < 0), so a
    running sum plus the remaining points' bound below the threshold settles it. Exact for every hypothesis
    that reaches the threshold, so the argmax is unchanged whenever some hypothesis reaches it.

    ``cells``: the points are those of an image grid (:class:`ImageCells`, in its order); each hypothesis
    then visits only the rows and columns it can reach, and the same points in the same order contribute,
    so the gains are bit for bit those without it.
    """
    params = inlier_params(tau, beta, tau_c, occlusion_aware)
    return gains_of(scoring_arrays(points, state, cells), centers, half_sizes, rotations, params, prune_below)


@njit(parallel=True, cache=True)
def _values(points, centers, half, rot, beta, inv_tau, tau_c, slope, offset, cutoff, oai, out):
    n = points.shape[0]
    cams = np.empty((centers.shape[0], 3))
    for h in range(centers.shape[0]):
        cams[h, 0], cams[h, 1], cams[h, 2] = camera_local(centers[h, 0], centers[h, 1], centers[h, 2], rot[h])
    for i in prange(n):
        for h in range(centers.shape[0]):
            R = rot[h]
            t0, t1, t2 = centers[h, 0], centers[h, 1], centers[h, 2]
            c0, c1, c2 = cams[h, 0], cams[h, 1], cams[h, 2]
            x = points[i, 0] - t0
            y = points[i, 1] - t1
            z = points[i, 2] - t2
            l0, l1, l2 = to_local(x, y, z, R)
            out[h, i] = pair_value(
                l0,
                l1,
                l2,
                half[h, 0],
                half[h, 1],
                half[h, 2],
                c0,
                c1,
                c2,
                beta,
                inv_tau,
                tau_c,
                slope,
                offset,
                cutoff,
                oai,
            )


def cuboid_values(
    points,
    centers,
    half_sizes,
    rotations,
    tau: float,
    beta: float,
    tau_c: float,
    occlusion_aware: bool = True,
) -> np.ndarray:
    """f_OAI(y, {h}) of each cuboid on its own: (H, N) float64 (numpy in, numpy out)."""
    out = np.empty((centers.shape[0], points.shape[0]), dtype=np.float64)
    _values(
        *_f64(points, centers, half_sizes, rotations), *inlier_params(tau, beta, tau_c, occlusion_aware), out
    )
    return out

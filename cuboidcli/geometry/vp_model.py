"""The residual of a line segment for a vanishing point, and the refinement of Manhattan frames on it.

A Manhattan frame is a rotation R (columns: three orthogonal scene directions d_k) with a focal length;
its vanishing points are v_k ~ K d_k. A segment's residual for a vanishing point is the distance of its
endpoints from the line through its midpoint and the vanishing point (Tardif, "Non-iterative approach for
fast and accurate vanishing point detection", ICCV 2009): zero when the segment points at it. Frames are
refined by iteratively re-weighted Gauss-Newton on these residuals (:func:`refine_frames`), many at once.

Image coordinates here are centred and scaled: ((u - cx) / s, (v - cy) / s) with s the image's long
side, and focal lengths phi = fx / s; K = diag(phi, aspect phi, 1) in these coordinates.
"""

from __future__ import annotations

import numpy as np


class Segments:
    """Segments (N, 4) ``x1, y1, x2, y2`` in pixels, kept in centred, scaled coordinates: ``line`` (N, 3),
    ``quad`` (N, 5) (the denominator's coefficients, below), ``half`` (N,) half lengths and ``weight``
    (N,) lengths relative to their mean.

    A segment's residual for a vanishing point v (homogeneous) is h (l . v) / |v_xy - v_z m|: h its half
    length, m its midpoint and l its line scaled so that (l0, l1) is a unit normal (l . v / |...| is the sine
    of the angle at m between the segment and the line to v). The squared denominator is linear in the
    monomials (vx^2, vy^2, vz^2, vx vz, vy vz), so the residuals of many hypotheses are matrix products.
    """

    def __init__(self, segs: np.ndarray, cx: float, cy: float, scale: float):
        a = (segs[:, :2] - (cx, cy)) / scale
        b = (segs[:, 2:] - (cx, cy)) / scale
        length = np.linalg.norm(b - a, axis=1)
        mid = (a + b) / 2
        line = np.cross(np.c_[a, np.ones(len(a))], np.c_[b, np.ones(len(b))])
        self.line = line / np.linalg.norm(line[:, :2], axis=1, keepdims=True)
        one = np.ones(len(a))
        self.quad = np.c_[one, one, (mid**2).sum(1), -2 * mid[:, 0], -2 * mid[:, 1]]
        self.half = length / 2
        self.weight = length / length.mean()

    def take(self, which) -> Segments:
        """The segments ``which`` (a slice, indices or a mask)."""
        out = object.__new__(Segments)
        for k in ("line", "quad", "half", "weight"):
            setattr(out, k, getattr(self, k)[which])
        return out


def _monomials(v: np.ndarray) -> np.ndarray:
    x, y, z = v[..., 0], v[..., 1], v[..., 2]
    return np.stack([x * x, y * y, z * z, x * z, y * z], axis=-1)


def vanishing_points(rot: np.ndarray, phi, aspect: float) -> np.ndarray:
    """(..., 3 columns, 3) homogeneous vanishing points, in scaled coordinates, of rotations (..., 3, 3)
    with focal lengths phi (...,) in units of the long side."""
    scale = np.stack([phi, aspect * np.asarray(phi), np.ones_like(phi)], axis=-1)
    return np.swapaxes(rot, -1, -2) * scale[..., None, :]


def residuals(vps: np.ndarray, lines: Segments) -> np.ndarray:
    """(..., 3, N) each segment's signed residual for each vanishing point of vps (..., 3, 3)."""
    den2 = _monomials(vps) @ lines.quad.T
    return (vps @ lines.line.T) * (lines.half / np.sqrt(np.maximum(den2, 1e-24)))


def _own_residuals(vps: np.ndarray, labels: np.ndarray, lines: Segments) -> np.ndarray:
    """(B, N) each segment's residual for its own vanishing point ``vps[b, labels[b]]`` (vps (B, 3, 3))."""
    v = vps[np.arange(len(vps))[:, None], labels]
    den2 = (_monomials(v) * lines.quad).sum(-1)
    return (v * lines.line).sum(-1) * (lines.half / np.sqrt(np.maximum(den2, 1e-24)))


def msac_cost(rot, phi, lines: Segments, aspect: float, thr: float) -> np.ndarray:
    """(...,) MSAC cost of frames rot (..., 3, 3) at focal lengths phi (...,): the sum over segments of
    weight * min(residual^2, thr^2), residual and thr in scaled units (pixels / s).

    Computed on squares in single precision: it only ranks hypotheses, and it is most of the time spent.
    """
    v = vanishing_points(rot, phi, aspect).astype(np.float32)
    num = v @ lines.line.T.astype(np.float32)
    den2 = np.maximum(_monomials(v) @ lines.quad.T.astype(np.float32), np.float32(1e-24))
    r2 = (num * num / den2).min(axis=-2) * (lines.half**2).astype(np.float32)
    return np.minimum(r2, np.float32(thr**2)).astype(np.float64) @ lines.weight


def _rotations(w: np.ndarray) -> np.ndarray:
    """(B, 3, 3) rotations of rotation vectors w (B, 3) (Rodrigues)."""
    t = np.linalg.norm(w, axis=-1)[:, None, None]
    k = np.zeros((len(w), 3, 3))
    k[:, 0, 1], k[:, 0, 2], k[:, 1, 2] = -w[:, 2], w[:, 1], -w[:, 0]
    k -= np.swapaxes(k, 1, 2)
    ts = np.maximum(t, 1e-12)
    return np.eye(3) + np.sin(t) / ts * k + (1 - np.cos(t)) / ts**2 * k @ k


def _linearise(rot, phi, lines: Segments, aspect: float, npar: int):
    """Each segment's residual for its nearest vanishing point and its derivatives, for B frames.

    Returns (r (B, N), labels (B, N), J (B, N, npar)): J along a small rotation w (d_k -> d_k + w x d_k,
    on the left) and, with npar 4, log phi.
    """
    b = np.arange(len(rot))[:, None]
    v = vanishing_points(rot, phi, aspect)
    res = residuals(v, lines)
    lab = np.abs(res).argmin(axis=-2)
    r = np.take_along_axis(res, lab[:, None], axis=1)[:, 0]
    vi, c = v[b, lab], lines.quad  # (B, N, 3): each segment's own vanishing point
    q = (_monomials(vi) * c).sum(-1)
    grad_q = np.stack(
        [2 * c[:, 0] * vi[..., 0] + c[:, 3] * vi[..., 2], 2 * c[:, 1] * vi[..., 1] + c[:, 4] * vi[..., 2],
         2 * c[:, 2] * vi[..., 2] + c[:, 3] * vi[..., 0] + c[:, 4] * vi[..., 1]], -1,
    )  # fmt: skip
    lv = (vi * lines.line).sum(-1)
    drdv = lines.half[:, None] * (lines.line - (lv / (2 * q))[..., None] * grad_q) / np.sqrt(q)[..., None]
    # v_k = D d_k with D = diag(phi, a phi, 1): d v_k / d w = -D [d_k]x, d v_k / d log phi = (v_x, v_y, 0)
    d = np.swapaxes(rot, 1, 2)
    skew = np.zeros(d.shape + (3,))
    skew[..., 0, 1], skew[..., 0, 2], skew[..., 1, 2] = d[..., 2], -d[..., 1], d[..., 0]
    skew -= np.swapaxes(skew, -1, -2)
    scale = np.stack([phi, aspect * np.asarray(phi), np.ones_like(phi)], -1)[:, None, :, None]
    dvdp = np.concatenate([scale * skew, (v * (1.0, 1.0, 0.0))[..., None]], axis=-1)[..., :npar]
    return r, lab, np.einsum("bni,bnij->bnj", drdv, dvdp[b, lab])


def refine_frames(rot, phi, lines: Segments, aspect, thr, free_focal, phi_range, steps=8):
    """Iteratively re-weighted Gauss-Newton on B frames at once: rot (B, 3, 3), phi (B,).

    Each step assigns every segment to its nearest vanishing point, weights it by its length and a Huber
    weight (threshold thr in scaled units; beyond 3 thr it is left out), and moves each frame by a damped
    Gauss-Newton step in a small rotation and, with ``free_focal``, log phi (kept within phi_range, a
    (low, high) pair), halved until its cost drops. Returns (rot (B, 3, 3), phi (B,)).
    """
    rot, phi = rot.copy(), np.array(phi, dtype=np.float64)
    npar = 4 if free_focal else 3
    eye = np.eye(npar)
    for _ in range(steps):
        r, lab, jac = _linearise(rot, phi, lines, aspect, npar)
        w = lines.weight * np.minimum(1.0, thr / np.maximum(np.abs(r), 1e-12)) * (np.abs(r) < 3 * thr)
        jtj = np.einsum("bni,bn,bnj->bij", jac, w, jac)
        damp = 1e-6 * np.trace(jtj, axis1=1, axis2=2)[:, None, None] * eye + 1e-12 * eye
        step = -np.linalg.solve(jtj + damp, np.einsum("bni,bn->bi", jac, w * r)[..., None])[..., 0]
        if free_focal:
            step[:, 3] = np.clip(step[:, 3], np.log(phi_range[0] / phi), np.log(phi_range[1] / phi))
        cost0 = (w * r**2).sum(-1)
        todo = np.ones(len(rot), dtype=bool)
        for _ in range(4):  # halve the step until the cost drops
            new_rot = _rotations(step[:, :3]) @ rot
            new_phi = phi * np.exp(step[:, 3]) if free_focal else phi
            rn = _own_residuals(vanishing_points(new_rot, new_phi, aspect), lab, lines)
            better = todo & ((w * rn**2).sum(-1) < cost0)
            rot[better], phi[better] = new_rot[better], new_phi[better]
            todo &= ~better
            if not todo.any():
                break
            step /= 2
    return rot, phi


def frame_covariance(rot, phi, lines: Segments, aspect, thr, free_focal) -> np.ndarray:
    """(4, 4) covariance of (small rotation, log phi) of one frame from its supporting segments' residuals,
    each segment counted once whatever its length (neighbouring segments of one edge share its errors)."""
    npar = 4 if free_focal else 3
    r, _, jac = _linearise(rot[None], np.array([phi]), lines, aspect, npar)
    sel = np.abs(r[0]) < thr
    cov = np.full((4, 4), np.inf)
    if sel.sum() <= npar + 1:
        return cov
    jac, r = jac[0][sel], r[0][sel]
    info = jac.T @ jac
    if np.linalg.cond(info) > 1e12:
        return cov
    cov[:] = 0.0
    cov[:npar, :npar] = float(r @ r) / (len(r) - npar) * np.linalg.inv(info)
    return cov

"""Exact checks of the vanishing-point model and the Manhattan fit on segments drawn in code from a known
rotation and focal length (geometry/vp_model.py, geometry/manhattan_vp.py), of the confidences read off a
fit (geometry/vanishing.py) and of the segment detector's pixel bookkeeping (geometry/lines.py)."""

from __future__ import annotations

import dataclasses
import math

import cv2
import numpy as np
import pytest

from cuboidcli.geometry import lines as lines_mod
from cuboidcli.geometry import manhattan_vp as mvp
from cuboidcli.geometry import vanishing
from cuboidcli.geometry import vp_model as vm
from tests.geometry.test_vanishing import _axis_rotation

SIZE = (640, 480)
CX, CY = (SIZE[0] - 1) / 2, (SIZE[1] - 1) / 2
#: three finite vanishing points (a camera turned 35 degrees and pitched 20 degrees)
ROT = _axis_rotation(0, -20.0) @ _axis_rotation(1, 35.0)


def synth_segments(rot, fx, per=(20, 20, 20), seed=0, noise=0.0, size=SIZE):
    """Segments in pixels pointing exactly at the vanishing points K rot[:, k] (parallel to their
    direction when at infinity), ``per[k]`` for column k, and each segment's column."""
    rng = np.random.default_rng(seed)
    w, h = size
    k = np.array([[fx, 0, (w - 1) / 2], [0, fx, (h - 1) / 2], [0, 0, 1.0]])
    out, fam = [], []
    for a, n in enumerate(per):
        v = k @ rot[:, a]
        for _ in range(n):
            p = rng.uniform((60, 60), (w - 60, h - 60))
            u = v[:2] / v[2] - p if abs(v[2]) > 1e-9 else v[:2]
            u = u / np.linalg.norm(u)
            half = rng.uniform(20, 60)
            out.append(np.r_[p - half * u, p + half * u])
            fam.append(a)
    segs = np.array(out).reshape(-1, 4) + rng.normal(0, noise, (len(out), 4))
    return segs, np.array(fam)


def _same_axes(a, b, tol=1e-6) -> bool:
    """Two frames with the same three axes (any order and signs)."""
    return bool(np.allclose(np.sort(np.abs(a.T @ b), axis=1)[:, -1], 1.0, atol=tol))


# ---- vp_model ----------------------------------------------------------------------------------------


def test_segments_store_unit_normals_half_lengths_and_relative_weights():
    segs = np.array([[0.0, 0.0, 6.0, 8.0], [10.0, 10.0, 10.0, 30.0]])
    s = vm.Segments(segs, 2.0, 4.0, 10.0)
    assert np.allclose(s.half, [0.5, 1.0]) and np.allclose(s.weight, [10 / 15, 20 / 15])
    assert np.allclose(np.hypot(s.line[:, 0], s.line[:, 1]), 1.0)
    # both endpoints (centred, scaled) lie on the line
    for seg, line in zip(segs, s.line, strict=True):
        for x, y in (seg[:2], seg[2:]):
            assert line @ [(x - 2.0) / 10, (y - 4.0) / 10, 1.0] == pytest.approx(0.0, abs=1e-12)
    # the midpoints in the quadratic: |v_xy - v_z m|^2 for v = (0, 0, 1) is |m|^2
    assert np.allclose(s.quad[:, 2], [0.1**2 + 0.0**2, 0.8**2 + 1.6**2])
    sub = s.take([1])
    assert np.allclose(sub.half, [1.0]) and np.allclose(sub.weight, [20 / 15])


def test_residual_is_the_endpoint_distance_from_the_line_to_the_vanishing_point():
    # segment from (-1, 0) to (1, 0) (scaled units): half length 1, midpoint at the origin
    s = vm.Segments(np.array([[-1.0, 0.0, 1.0, 0.0]]), 0.0, 0.0, 1.0)
    vps = np.array(
        [
            [5.0, 0.0, 1.0],  # on the segment's line: 0
            [0.0, 3.0, 1.0],  # straight above the midpoint: the full half length
            [2.0, 2.0, 1.0],  # 45 degrees: sin 45
            [1.0, 1.0, 0.0],  # at infinity along 45 degrees: sin 45
            [2.0, 2.0 * math.tan(math.radians(30)), 2.0],  # finite, 30 degrees, not normalised: 0.5
        ]
    )
    r = np.abs(vm.residuals(vps[None, :3], s)[0, :, 0])
    assert np.allclose(r, [0.0, 1.0, math.sqrt(0.5)])
    r2 = np.abs(vm.residuals(vps[None, 2:], s)[0, :, 0])
    assert np.allclose(r2, [math.sqrt(0.5), math.sqrt(0.5), 0.5])
    # a longer segment (half length 3) at the same angle: three times the residual
    s3 = vm.Segments(np.array([[-3.0, 0.0, 3.0, 0.0]]), 0.0, 0.0, 1.0)
    assert abs(vm.residuals(vps[None, 2:], s3)[0, 2, 0]) == pytest.approx(1.5)
    # a segment away from the origin: from (1, 1) to (3, 1), the vanishing point straight above its
    # midpoint (2, 1), or 45 degrees off it, or at infinity along 45 degrees
    off = vm.Segments(np.array([[1.0, 1.0, 3.0, 1.0]]), 0.0, 0.0, 1.0)
    far = np.array([[2.0, 4.0, 1.0], [5.0, 4.0, 1.0], [-1.0, 1.0, 0.0]])
    assert np.allclose(np.abs(vm.residuals(far[None], off)[0, :, 0]), [1.0, math.sqrt(0.5), math.sqrt(0.5)])
    own = vm._own_residuals(vps[None, 2:], np.array([[1]]), s)
    assert own[0, 0] == pytest.approx(vm.residuals(vps[None, 2:], s)[0, 1, 0])


def test_vanishing_points_are_k_times_the_directions():
    v = vm.vanishing_points(ROT[None], np.array([0.8]), 1.5)[0]
    k = np.diag([0.8, 1.2, 1.0])
    assert np.allclose(v, (k @ ROT).T)


def test_msac_cost_sums_length_weighted_truncated_squares():
    segs, _ = synth_segments(ROT, 500.0, per=(4, 4, 4), noise=0.0)
    segs[0] += [0.0, 0.0, 0.0, 3.0]  # one segment bent off its vanishing point
    lines = vm.Segments(segs, CX, CY, 640.0)
    phi = np.array(500.0 / 640)
    r = np.abs(vm.residuals(vm.vanishing_points(ROT, phi, 1.0), lines)).min(axis=0)
    for thr in (1e-4, 1.0):  # the bent segment truncated, then not
        expected = sum(w * min(x * x, thr * thr) for w, x in zip(lines.weight, r, strict=True))
        assert vm.msac_cost(ROT, phi, lines, 1.0, thr) == pytest.approx(expected, rel=1e-5, abs=1e-14)
    assert r[0] > 1e-3 and np.all(r[1:] < 1e-9)


def test_rodrigues_rotations_match_opencv():
    w = np.array([[0.0, 0.0, 0.0], [0.3, -0.2, 0.1], [0.0, 0.0, math.pi / 2]])
    for wi, r in zip(w, vm._rotations(w), strict=True):
        assert np.allclose(r, cv2.Rodrigues(wi)[0], atol=1e-12)


def test_the_jacobian_matches_finite_differences():
    segs, _ = synth_segments(ROT, 500.0, per=(5, 5, 5), noise=0.5)
    lines = vm.Segments(segs, CX, CY, 640.0)
    phi, aspect = 500.0 / 640, 1.1
    r0, lab, jac = vm._linearise(ROT[None], np.array([phi]), lines, aspect, 4)
    eps = 1e-6
    for i in range(4):
        step = np.zeros(4)
        step[i] = eps
        rot = vm._rotations(step[None, :3])[0] @ ROT
        v = vm.vanishing_points(rot[None], np.array([phi * math.exp(step[3])]), aspect)
        num = (vm._own_residuals(v, lab, lines)[0] - r0[0]) / eps
        assert np.allclose(jac[0, :, i], num, atol=1e-5, rtol=1e-4), i
    _, _, jac3 = vm._linearise(ROT[None], np.array([phi]), lines, aspect, 3)
    assert np.allclose(jac3, jac[..., :3])


def test_refinement_recovers_the_rotation_and_the_focal_length():
    segs, _ = synth_segments(ROT, 500.0, per=(15, 15, 15))
    lines = vm.Segments(segs, CX, CY, 640.0)
    thr = 1.5 / 640
    start = (vm._rotations(np.array([[0.01, -0.008, 0.006]])) @ ROT)[None][0]
    rot, phi = vm.refine_frames(start, [500.0 / 640 * 1.06], lines, 1.0, thr, True, (0.3, 3.0))
    assert np.allclose(rot[0], ROT, atol=1e-6) and phi[0] * 640 == pytest.approx(500.0, rel=1e-6)
    # a fixed focal length stays, and the rotation still converges
    rot, phi = vm.refine_frames(start, [500.0 / 640], lines, 1.0, thr, False, (0.3, 3.0))
    assert phi[0] == 500.0 / 640 and np.allclose(rot[0], ROT, atol=1e-6)
    # the focal length is kept within its range
    _, phi = vm.refine_frames(ROT[None], [0.7], lines, 1.0, thr, True, (0.6, 0.72))
    assert 0.6 <= phi[0] <= 0.72 and phi[0] == pytest.approx(0.72)
    _, phi = vm.refine_frames(ROT[None], [0.85], lines, 1.0, thr, True, (0.8, 3.0))  # true 0.78: below
    assert phi[0] == pytest.approx(0.8)
    # segments far beyond 3 thresholds from their vanishing point are left out
    outliers = np.array([[100.0, 100.0, 300.0, 110.0], [500.0, 400.0, 520.0, 250.0]] * 10)
    mixed = vm.Segments(np.vstack([segs, outliers]), CX, CY, 640.0)
    rot, phi = vm.refine_frames(start, [500.0 / 640 * 1.06], mixed, 1.0, thr, True, (0.3, 3.0))
    assert np.allclose(rot[0], ROT, atol=1e-5) and phi[0] * 640 == pytest.approx(500.0, rel=1e-5)


def test_segments_beyond_three_thresholds_do_not_pull_the_frame():
    segs, _ = synth_segments(ROT, 500.0, per=(15, 15, 15), seed=7)
    thr = 1.5 / 640
    # six segments bent by 3.5 thresholds: each end moved 5.25 px across, in opposite directions
    bent = segs[::8][:6].copy()
    d = bent[:, 2:] - bent[:, :2]
    n = np.c_[-d[:, 1], d[:, 0]] / np.linalg.norm(d, axis=1, keepdims=True) * 3.5 * 1.5
    bent[:, :2] -= n
    bent[:, 2:] += n
    vps = vm.vanishing_points(ROT, 500.0 / 640, 1.0)
    r = np.abs(vm.residuals(vps, vm.Segments(bent, CX, CY, 640.0))).min(axis=0)
    bent = bent[np.isclose(r, 3.5 * thr, rtol=1e-6)]  # not nearer another vanishing point
    assert len(bent) >= 4
    lines = vm.Segments(np.vstack([segs, bent]), CX, CY, 640.0)
    start = vm._rotations(np.array([[0.004, -0.003, 0.002]])) @ ROT
    rot, phi = vm.refine_frames(start, [500.0 / 640 * 1.03], lines, 1.0, thr, True, (0.3, 3.0))
    assert np.allclose(rot[0], ROT, atol=1e-8) and phi[0] * 640 == pytest.approx(500.0, rel=1e-8)


def test_frame_covariance_is_the_residual_variance_through_the_jacobian():
    segs, _ = synth_segments(ROT, 500.0, per=(15, 15, 15), noise=0.3, seed=2)
    lines = vm.Segments(segs, CX, CY, 640.0)
    thr = 1.5 / 640
    rot, phi = vm.refine_frames(ROT[None], [500.0 / 640], lines, 1.0, thr, True, (0.3, 3.0))
    cov = vm.frame_covariance(rot[0], phi[0], lines, 1.0, thr, True)
    r, _, jac = vm._linearise(rot, phi, lines, 1.0, 4)
    sel = np.abs(r[0]) < thr
    n = int(sel.sum())
    assert n > 40
    j, res = jac[0][sel], r[0][sel]
    # the unbiased variance of n residuals with 4 parameters, through the inverse information
    expected = np.linalg.inv(j.T @ j) * float(np.sum(res**2)) / (n - 4)
    assert np.allclose(cov, expected, rtol=1e-9)
    assert np.all(np.linalg.eigvalsh(cov) > 0)
    fixed = vm.frame_covariance(rot[0], phi[0], lines, 1.0, thr, False)
    assert np.all(fixed[3] == 0) and np.all(fixed[:, 3] == 0)
    assert np.allclose(fixed[:3, :3], np.linalg.inv(j[:, :3].T @ j[:, :3]) * np.sum(res**2) / (n - 3))
    # too few supporting segments (npar + 1 or fewer): unknown; one more: known
    support = np.array(sorted(np.flatnonzero(sel), key=lambda i: (i % 15, i // 15)))  # the columns in turn
    for npar, free in ((4, True), (3, False)):
        few = vm.frame_covariance(rot[0], phi[0], lines.take(support[: npar + 1]), 1.0, thr, free)
        assert np.all(np.isinf(few))
        enough = vm.frame_covariance(rot[0], phi[0], lines.take(support[: npar + 2]), 1.0, thr, free)
        assert np.all(np.isfinite(enough))


# ---- manhattan_vp ------------------------------------------------------------------------------------


def test_the_focal_length_of_three_finite_vanishing_points_is_recovered():
    segs, fam = synth_segments(ROT, 500.0, per=(20, 16, 24))
    fit = mvp.fit_manhattan(segs, SIZE)
    assert fit.focal_px == pytest.approx(500.0, rel=1e-6) and fit.aspect == 1.0
    assert _same_axes(fit.rotation, ROT) and fit.rms_px < 1e-6
    assert fit.principal_px == (CX, CY)
    # each segment labelled with the column along its direction, the support its share of the length
    col = np.abs(ROT.T @ fit.rotation).argmax(axis=1)
    assert np.array_equal(fit.labels, col[fam])
    length = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1])
    for a in range(3):
        assert fit.support[col[a]] == pytest.approx(length[fam == a].sum() / length.sum())
    # one frame explains the segments, no other focal length comes close
    assert fit.focal_margin > 10
    assert np.all(np.isfinite(fit.covariance)) and fit.covariance[3, 3] > 0
    # the vanishing points in pixels
    vps = fit.vanishing_points()
    k = np.array([[500.0, 0, CX], [0, 500.0, CY], [0, 0, 1]])
    for v in (k @ ROT).T:
        assert min(np.linalg.norm(np.cross(v, u)) / np.linalg.norm(v) / np.linalg.norm(u) for u in vps) < 1e-6


@pytest.mark.parametrize("fx", [300.0, 900.0])
def test_other_focal_lengths_and_a_given_one(fx):
    rot = _axis_rotation(0, -25.0) @ _axis_rotation(1, 40.0)
    segs, _ = synth_segments(rot, fx, seed=1)
    free = mvp.fit_manhattan(segs, SIZE)
    assert free.focal_px == pytest.approx(fx, rel=1e-4) and _same_axes(free.rotation, rot)
    given = mvp.fit_manhattan(segs, SIZE, fx=fx)
    assert given.focal_px == fx and given.focal_margin == 0.0 and _same_axes(given.rotation, rot)
    assert np.all(given.covariance[3] == 0) and np.all(given.covariance[:, 3] == 0)
    only_fy = mvp.fit_manhattan(segs, SIZE, fy=fx)
    assert only_fy.focal_px == fx and only_fy.aspect == 1.0


def test_a_given_aspect_and_principal_point():
    rot = _axis_rotation(0, -20.0) @ _axis_rotation(1, 30.0)
    fx, fy, cx, cy = 500.0, 550.0, 300.0, 250.0
    k = np.array([[fx, 0, cx], [0, fy, cy], [0, 0, 1.0]])
    rng = np.random.default_rng(3)
    segs = []
    for a in range(3):
        v = k @ rot[:, a]
        for _ in range(15):
            p = rng.uniform((60, 60), (580, 420))
            u = (v[:2] / v[2] - p) / np.linalg.norm(v[:2] / v[2] - p)
            segs.append(np.r_[p - 30 * u, p + 30 * u])
    fit = mvp.fit_manhattan(np.array(segs), SIZE, fx=fx, fy=fy, cx=cx, cy=cy)
    assert fit.aspect == pytest.approx(1.1) and fit.principal_px == (cx, cy)
    assert _same_axes(fit.rotation, rot) and fit.rms_px < 1e-6 and np.all(fit.labels >= 0)


def test_fewer_than_the_minimum_segments_give_no_fit():
    segs, _ = synth_segments(ROT, 500.0, per=(4, 4, 4))
    n = mvp.MIN_SEGMENTS
    assert mvp.fit_manhattan(segs[: n - 1], SIZE) is None
    assert mvp.fit_manhattan(segs[:n], SIZE, fx=500.0) is not None


def test_the_focal_length_is_searched_within_the_field_of_view_range():
    # a 20 degree field of view: the narrowest of the range is the nearest the search gets
    fx = 320.0 / math.tan(math.radians(10.0))
    fit = mvp.fit_manhattan(synth_segments(ROT, fx, seed=2)[0], SIZE)
    narrowest = 320.0 / math.tan(math.radians(min(mvp.FOV_RANGE_DEG) / 2))
    assert fit.focal_px == pytest.approx(narrowest, rel=1e-6)


def test_segments_off_every_vanishing_point_are_unlabelled_and_left_out_of_the_rms():
    segs, fam = synth_segments(ROT, 500.0, per=(15, 15, 15), noise=0.4, seed=6)
    off = np.array([[100.0, 100.0, 160.0, 300.0], [500.0, 100.0, 380.0, 420.0], [50.0, 400.0, 300.0, 330.0]])
    fit = mvp.fit_manhattan(np.vstack([segs, off]), SIZE, fx=500.0)
    assert fit.support.shape == (3,) and np.all(fit.labels[-3:] == -1) and np.all(fit.labels[:-3] >= 0)
    # the rms of the supporting segments: each endpoint's distance from the line through the segment's
    # midpoint and its vanishing point, in pixels (the image is 640 px wide: no rescaling)
    vps = fit.vanishing_points()
    d = []
    for seg, lab in zip(segs, fit.labels[:-3], strict=True):
        v, a, b = vps[lab], seg[:2], seg[2:]
        m = (a + b) / 2
        u = v[:2] - v[2] * m  # the direction from the midpoint towards the vanishing point
        d.append(abs(u[0] * (b - m)[1] - u[1] * (b - m)[0]) / np.linalg.norm(u))
    assert fit.rms_px == pytest.approx(math.sqrt(np.mean(np.square(d))), rel=1e-6)
    assert 0.1 < fit.rms_px < 0.6
    with pytest.raises(dataclasses.FrozenInstanceError):
        fit.focal_px = 1.0


def test_segments_all_on_one_line_give_no_frame():
    # every triple of segments has parallel interpretation planes: no hypothesis, no fit
    one_line = np.array([[10.0 + 30 * i, 100.0 + 10 * i, 40.0 + 30 * i, 110.0 + 10 * i] for i in range(15)])
    assert mvp.fit_manhattan(one_line, SIZE) is None
    assert mvp.fit_manhattan(one_line, SIZE, fx=500.0) is None


def test_a_big_photos_residuals_are_in_pixels_of_the_640_px_copy():
    # the same segments in a 1280 x 960 photo: twice the pixels, the same rms at 640 px
    segs, _ = synth_segments(ROT, 500.0, noise=0.3, seed=4)
    small = mvp.fit_manhattan(segs, SIZE, fx=500.0)
    big = mvp.fit_manhattan(segs * 2 + 0.5, (1280, 960), fx=1000.0)
    assert big.rms_px == pytest.approx(small.rms_px, rel=1e-3)
    assert 0.1 < small.rms_px < 0.5 and np.array_equal(small.labels, big.labels)


def test_a_level_camera_facing_a_wall_leaves_the_focal_length_ambiguous():
    # two vanishing points at infinity: any focal length explains the segments (only the prior decides,
    # against the 29 segments' worth of three finite vanishing points), and the covariance is unknown
    segs, _ = synth_segments(_axis_rotation(1, 0.0), 500.0, per=(20, 20, 20))
    fit = mvp.fit_manhattan(segs, SIZE)
    assert fit.focal_margin < 3.0 and np.all(np.isinf(fit.covariance))
    # the prior decides: its field of view
    assert fit.focal_px == pytest.approx(320.0 / math.tan(math.radians(mvp.PRIOR_FOV_DEG / 2)), rel=1e-6)
    assert fit.rms_px < 1e-6 and _same_axes(fit.rotation, np.eye(3))


def test_the_likelihood_profile_is_zero_at_the_estimate_and_grows_away_from_it():
    segs, _ = synth_segments(ROT, 500.0, per=(20, 16, 24), noise=0.3, seed=2)
    fit = mvp.fit_manhattan(segs, SIZE)
    prof = fit.profile
    assert prof.shape == (mvp.LIKELIHOOD_STEPS, 2)
    # log-spaced focal lengths over the field-of-view range of the long side
    lo, hi = (320.0 / math.tan(math.radians(a / 2)) for a in mvp.FOV_RANGE_DEG[::-1])
    assert prof[0, 0] == pytest.approx(lo) and prof[-1, 0] == pytest.approx(hi)
    assert np.allclose(np.diff(np.log(prof[:, 0])), math.log(hi / lo) / (mvp.LIKELIHOOD_STEPS - 1))
    # segments' worth relative to the fit: about 0 next to it, nothing better, far worse 30 % away
    near = np.abs(np.log(prof[:, 0] / fit.focal_px)) < 0.025
    assert near.any() and prof[near, 1].min() < 1.0
    assert prof[:, 1].min() > -0.1
    far = np.abs(np.log(prof[:, 0] / 500.0)) > math.log(1.3)
    assert prof[far, 1].min() > 10.0
    assert mvp.fit_manhattan(segs, SIZE, fx=500.0).profile.shape == (0, 2)  # a given focal length


def test_facing_a_wall_the_likelihood_profile_is_the_priors():
    # two vanishing points at infinity: every focal length explains the segments alike, but for the prior
    segs, _ = synth_segments(_axis_rotation(1, 0.0), 500.0, per=(20, 20, 20))
    fit = mvp.fit_manhattan(segs, SIZE)
    phi0 = 0.5 / math.tan(math.radians(mvp.PRIOR_FOV_DEG / 2))
    prior = mvp.PRIOR_WEIGHT * (np.log(fit.profile[:, 0] / 640.0 / phi0) / mvp.PRIOR_SIGMA) ** 2
    assert np.allclose(fit.profile[:, 1], prior, atol=1e-3)


def test_three_segments_give_their_frame():
    segs, _ = synth_segments(ROT, 500.0, per=(2, 1, 0))
    lines = vm.Segments(segs, CX, CY, 640.0)

    class Pick:  # the sampler's draw: the given segment triples
        def __init__(self, idx):
            self.idx = np.array(idx)

        def choice(self, n, size, p):
            assert np.allclose(p.sum(), 1.0) and size == (len(self.idx), 3)
            return self.idx

    phis = np.full(3, 500.0 / 640)
    rots, ok = mvp._hypotheses(lines, Pick([[0, 1, 2], [0, 0, 2], [2, 0, 1]]), phis, 1.0)
    assert list(ok) == [True, False, True]  # a repeated segment defines no direction
    assert np.allclose(np.abs(rots[0][:, 0] @ ROT[:, 0]), 1.0) and np.allclose(
        np.abs(rots[0][:, 1] @ ROT[:, 1]), 1
    )
    assert _same_axes(rots[0], ROT) and np.allclose(np.linalg.det(rots[0]), 1.0)


def test_the_prior_is_zero_at_its_field_of_view_and_one_weight_one_sigma_away():
    phi0 = 0.5 / math.tan(math.radians(mvp.PRIOR_FOV_DEG) / 2)  # in units of the long side
    one = mvp.PRIOR_WEIGHT * 0.01**2  # one sigma: PRIOR_WEIGHT segments at the threshold
    assert mvp._prior(phi0, 0.01) == pytest.approx(0.0, abs=1e-15)
    assert mvp._prior(phi0 * math.exp(mvp.PRIOR_SIGMA), 0.01) == pytest.approx(one)
    assert mvp._prior(phi0 / math.exp(2 * mvp.PRIOR_SIGMA), 0.01) == pytest.approx(4 * one)


def test_profile_starts_are_the_parabola_minima_of_the_two_best_local_minima():
    grid = np.geomspace(0.5, 2.0, 9)
    x = np.log(grid)
    costs = np.minimum((x - 0.3) ** 2, (x + 0.45) ** 2 + 0.05)  # two minima, the first lower
    rots = np.stack([np.eye(3) * (j + 1) for j in range(9)])
    starts = mvp._profile_starts(grid, rots, costs)
    assert len(starts) == 2
    assert starts[0][1] == pytest.approx(math.exp(0.3), rel=1e-9)
    assert starts[1][1] == pytest.approx(math.exp(-0.45), rel=1e-9)
    assert np.array_equal(starts[0][0], rots[np.argmin(np.abs(x - 0.3))])
    # a minimum at the grid's end is not moved; a flat bottom (no curvature) neither
    edge = mvp._profile_starts(grid, rots, (x - x[0]) ** 2 + 0.0)
    assert edge[0][1] == pytest.approx(grid[0]) and len(edge) == 1
    end = mvp._profile_starts(grid, rots, -x)
    assert end[0][1] == pytest.approx(grid[-1]) and len(end) == 1
    # a minimum next to the grid's last point is moved too
    near_end = mvp._profile_starts(grid, rots, (x - 0.6) ** 2)
    assert len(near_end) == 1 and near_end[0][1] == pytest.approx(math.exp(0.6), rel=1e-9)
    # a shallow parabola high above zero is still a parabola
    high = mvp._profile_starts(grid, rots, (x - 0.3) ** 2 + 10.0)
    assert high[0][1] == pytest.approx(math.exp(0.3), rel=1e-9)
    # local minima are lower than their immediate neighbours only
    for c in ([3.0, 1.0, 2.0, 0.5, 2.0, 3.0, 4.0, 5.0, 6.0], [2.0, 0.5, 3.0, 1.0, 2.0, 3.0, 4.0, 5.0, 6.0]):
        assert len(mvp._profile_starts(grid, rots, np.array(c))) == 2
    flat = mvp._profile_starts(grid[:3], rots[:3], np.array([1.0, 1.0, 1.0]))
    assert [s[1] for s in flat] == pytest.approx([grid[0], grid[1]])


def test_distinct_best_frames_differ_by_more_than_five_degrees():
    r = vm._rotations(np.array([[0, 0, 0], [0, 0, math.radians(3)], [0, 0, math.radians(8)], [0.5, 0, 0]]))
    # the same axes in another order and signs count as the same frame
    swapped = r[0][:, [1, 0, 2]] * [1, -1, 1]
    rots = np.concatenate([r, swapped[None]])
    cost = np.array([1.0, 2.0, 3.0, np.inf, 0.5])
    assert mvp._distinct_best(rots, cost, 3) == [4, 2]  # 0 and 1 as 4; 3 never (infinite cost)
    assert mvp._distinct_best(rots, cost, 1) == [4]
    assert mvp._distinct_best(rots, cost, 3, min_deg=2.0) == [4, 1, 2]
    four = vm._rotations(np.array([[0.0, 0.0, 0.0], [0.0, 0.0, math.radians(4.0)]]))
    assert mvp._distinct_best(four, np.array([1.0, 2.0]), 2) == [0]


# ---- vanishing ---------------------------------------------------------------------------------------


def _fit(rot, support, cov=None, margin=10.0, focal=500.0):
    return mvp.ManhattanFit(
        rotation=rot,
        focal_px=focal,
        aspect=1.0,
        principal_px=(CX, CY),
        labels=np.zeros(0, int),
        support=np.array(support, dtype=float),
        rms_px=0.5,
        covariance=np.zeros((4, 4)) if cov is None else cov,
        focal_margin=margin,
    )


def test_down_is_the_axis_nearest_the_hint_signed_and_the_horizontals_ordered_by_support():
    rot = _axis_rotation(0, -10.0)  # column 1: down tilted 10 degrees
    est = vanishing.line_estimate(_fit(rot, [0.1, 0.3, 0.25]), 36)
    assert np.allclose(est.down, rot[:, 1]) and est.down[1] > 0
    assert est.support == (0.3, 0.25, 0.1)  # up, then the better supported horizontal
    assert np.allclose(np.abs(est.axes[:, 1]), np.abs(rot[:, 2]))
    assert np.allclose(est.axes[:, 0], -est.down) and np.linalg.det(est.axes) == pytest.approx(1.0)
    flipped = vanishing.line_estimate(_fit(-rot, [0.1, 0.3, 0.25]), 36)
    assert np.allclose(flipped.down, est.down)
    sideways = vanishing.line_estimate(_fit(rot, [0.1, 0.3, 0.25]), 36, up_hint=np.array([2.0, 0.0, 0.0]))
    assert np.allclose(sideways.down, -rot[:, 0])
    for bad in (np.zeros(3), np.array([np.nan, 1.0, 0.0]), np.ones(2)):
        with pytest.raises(ValueError):
            vanishing.line_estimate(_fit(rot, [0.1, 0.3, 0.25]), 36, up_hint=bad)


def _support_for(coherence: float, n: int, vertical: float) -> list[float]:
    """Supports (columns 0, 1, 2; column 1 vertical) of ``n`` segments whose total is ``coherence`` of
    the coherent span beyond chance, split between the horizontals 3 : 1."""
    chance = vanishing.CHANCE_BASE + vanishing.CHANCE_SCALE / math.sqrt(n)
    rest = chance + coherence * vanishing.COHERENT_SPAN - vertical
    return [0.75 * rest, vertical, 0.25 * rest]


def test_the_down_confidence_grows_with_support_beyond_chance_and_falls_with_its_spread():
    rot = np.eye(3)  # down along column 1
    ev = vanishing.DOWN_EVIDENCE
    # the vertical and the weaker horizontal well beyond DOWN_EVIDENCE: the coherence alone
    sup = _support_for(0.75, 36, vertical=ev)
    assert sup[1] + sup[2] > ev
    assert vanishing.line_estimate(_fit(rot, sup), 36).down_confidence == pytest.approx(0.75)
    # fewer segments make the same support less likely by chance: full confidence
    assert vanishing.line_estimate(_fit(rot, sup), 10_000).down_confidence == 1.0
    # no support beyond chance: nothing
    assert vanishing.line_estimate(_fit(rot, _support_for(0.0, 36, ev)), 36).down_confidence == 0.0
    # the vertical and the weaker horizontal holding 0.4 of DOWN_EVIDENCE: 0.4 of the coherence
    weak = [0.5, 0.2 * ev, 0.2 * ev]
    n = int(
        round(
            (vanishing.CHANCE_SCALE / (sum(weak) - 0.6 * vanishing.COHERENT_SPAN - vanishing.CHANCE_BASE))
            ** 2
        )
    )
    chance = vanishing.CHANCE_BASE + vanishing.CHANCE_SCALE / math.sqrt(n)
    coherence = (sum(weak) - chance) / vanishing.COHERENT_SPAN
    assert 0.1 < coherence < 1
    assert vanishing.line_estimate(_fit(rot, weak), n).down_confidence == pytest.approx(0.4 * coherence)
    # a spread of DOWN_SIGMA_DEG across up: 1/e of it; a spread about the vertical is harmless
    a = math.radians(vanishing.DOWN_SIGMA_DEG) ** 2
    across = vanishing.line_estimate(_fit(rot, sup, np.diag([a, 0.0, 0.0, 0.0])), 36)
    assert across.down_confidence == pytest.approx(0.75 / math.e)
    both = vanishing.line_estimate(_fit(rot, sup, np.diag([a / 2, 0.0, a / 2, 0.0])), 36)
    assert both.down_confidence == pytest.approx(0.75 / math.e)
    along = vanishing.line_estimate(_fit(rot, sup, np.diag([0.0, 9 * a, 0.0, 0.0])), 36)
    assert along.down_confidence == pytest.approx(0.75)
    # the same for a tilted camera: the spread split evenly between the two directions across its up
    tilted = _axis_rotation(0, 30.0) @ _axis_rotation(2, 20.0)
    up = -vanishing.line_estimate(_fit(tilted, sup), 36).down
    spread = np.zeros((4, 4))
    spread[:3, :3] = a / 2 * (np.eye(3) - np.outer(up, up)) + 5 * a * np.outer(up, up)
    tilted_est = vanishing.line_estimate(_fit(tilted, sup, spread), 36)
    assert tilted_est.down_confidence == pytest.approx(0.75 / math.e)
    unknown = vanishing.line_estimate(_fit(rot, sup, np.full((4, 4), np.inf)), 36)
    assert unknown.down_confidence == 0.0
    # one family alone (the others below MIN_SUPPORT) leaves a rotation about it free
    lo = vanishing.MIN_SUPPORT
    assert vanishing.line_estimate(_fit(rot, [0.99 * lo, 0.9, 0.99 * lo]), 400).down_confidence == 0.0
    assert vanishing.line_estimate(_fit(rot, [lo, 0.9, 0.0]), 400).down_confidence > 0.5
    assert vanishing.line_estimate(_fit(rot, [0.9, 0.99 * lo, lo]), 400).down_confidence > 0.0


def test_the_focal_confidence_needs_the_two_central_vanishing_points():
    # columns 0 and 2 nearest the centre (column 1, nearly vertical, looks 80 degrees away)
    rot = _axis_rotation(1, 40.0) @ _axis_rotation(0, 10.0)
    tan = np.hypot(rot[0], rot[1]) / np.abs(rot[2])
    pair = list(np.argsort(tan)[:2])
    assert sorted(pair) == [0, 2]
    sd = vanishing.FOCAL_SIGMA  # relative spread of the focal length: 1/e
    cov = np.diag([0.0, 0.0, 0.0, sd**2])
    ev, margin = vanishing.FOCAL_EVIDENCE, vanishing.FOCAL_MARGIN
    support = np.array([0.5 * ev, 0.3, 2 * ev])  # the weaker of the pair: half of FOCAL_EVIDENCE
    f, conf = vanishing._focal_confidence(_fit(rot, support, cov, margin=0.5 * margin))
    assert f == 500.0 and conf == pytest.approx(0.5 * 0.5 / math.e)
    swapped = support[[2, 1, 0]]
    assert vanishing._focal_confidence(_fit(rot, swapped, cov, margin=0.5 * margin))[1] == pytest.approx(conf)
    # turning the camera about its optical axis moves no vanishing point nearer the centre
    turned = _axis_rotation(2, 90.0) @ rot
    assert vanishing._focal_confidence(_fit(turned, support, cov, margin=0.5 * margin))[1] == pytest.approx(
        conf
    )
    far = support.copy()
    far[1] = 0.0  # the far one does not matter
    assert vanishing._focal_confidence(_fit(rot, far, cov, margin=0.5 * margin))[1] == pytest.approx(conf)
    full = vanishing._focal_confidence(_fit(rot, np.full(3, 2 * ev), np.zeros((4, 4)), margin=2 * margin))
    assert full[1] == 1.0
    unseen = support.copy()
    unseen[0] = 0.99 * vanishing.MIN_SUPPORT
    assert vanishing._focal_confidence(_fit(rot, unseen, cov)) == (None, 0.0)
    seen = support.copy()
    seen[0] = vanishing.MIN_SUPPORT
    assert vanishing._focal_confidence(_fit(rot, seen, cov))[0] == 500.0
    inf_cov = np.diag([0.0, 0.0, 0.0, np.inf])
    assert vanishing._focal_confidence(_fit(rot, support, inf_cov)) == (None, 0.0)
    assert vanishing._focal_confidence(_fit(rot, support, cov, margin=-3.0))[1] == 0.0
    # scaled by the coherence in line_estimate; a given focal length: none
    sup = np.array([ev, 0.0, ev])
    n = int(
        round(
            (vanishing.CHANCE_SCALE / (sum(sup) - 0.5 * vanishing.COHERENT_SPAN - vanishing.CHANCE_BASE)) ** 2
        )
    )
    coherence = (
        sum(sup) - vanishing.CHANCE_BASE - vanishing.CHANCE_SCALE / math.sqrt(n)
    ) / vanishing.COHERENT_SPAN
    assert 0.1 < coherence < 1
    est = vanishing.line_estimate(_fit(rot, sup, np.zeros((4, 4)), margin=2 * margin), n)
    assert est.focal_px == 500.0 and est.focal_confidence == pytest.approx(coherence)
    given = vanishing.line_estimate(_fit(rot, sup, margin=2 * margin), n, focal_given=True)
    assert given.focal_px is None and given.focal_confidence == 0.0


def test_the_focal_spread_carries_the_principal_point_through_the_two_central_vanishing_points():
    f, sd_fit = 500.0, 0.02
    fit = dataclasses.replace(
        _fit(ROT, [0.3, 0.3, 0.3], np.diag([0.0, 0.0, 0.0, sd_fit**2]), focal=f), size=SIZE
    )
    tan = np.hypot(ROT[0], ROT[1]) / np.abs(ROT[2])
    v1, v2 = (f * ROT[:2, k] / ROT[2, k] + (CX, CY) for k in np.argsort(tan)[:2])

    def log_focal(c):  # orthogonal directions: f^2 = -(v1 - c).(v2 - c)
        return 0.5 * math.log(-float(np.dot(v1 - c, v2 - c)))

    c0, eps = np.array([CX, CY]), 1e-3
    grad = [(log_focal(c0 + eps * e) - log_focal(c0 - eps * e)) / (2 * eps) for e in np.eye(2)]
    assert log_focal(c0) == pytest.approx(math.log(f))
    sigma_c = vanishing.PRINCIPAL_SIGMA * 640
    expected = math.hypot(sd_fit, float(np.linalg.norm(grad)) * sigma_c)
    assert vanishing._focal_spread(fit) == pytest.approx(expected, rel=1e-5)
    assert expected > 1.3 * sd_fit  # the principal point's share is not negligible here
    # the far vanishing point does not enter; one of the central two at infinity: no spread
    assert vanishing._focal_spread(dataclasses.replace(fit, size=(640, 100))) == pytest.approx(expected)
    wall = dataclasses.replace(fit, rotation=_axis_rotation(1, 0.0))
    assert vanishing._focal_spread(wall) == math.inf
    # recorded by line_estimate with the estimate, and not for a given focal length
    assert vanishing.line_estimate(fit, 400).focal_sd == pytest.approx(expected, rel=1e-5)
    assert vanishing.line_estimate(fit, 400, focal_given=True).focal_sd == math.inf


def _profiled(worse, focal_sd=0.05, focal=500.0):
    """A line estimate at ``focal`` px whose likelihood profile is worse(fx) segments' worth."""
    fx = 500.0 * 1.05 ** np.arange(-19.0, 20.0)  # 198 to 1264 px
    fit = dataclasses.replace(_fit(ROT, [0.3, 0.3, 0.3], focal=focal), profile=np.c_[fx, worse(fx)])
    return dataclasses.replace(vanishing.line_estimate(fit, 400), focal_sd=focal_sd)


def test_an_unsure_estimate_rules_out_a_focal_length_the_segments_fit_worse():
    def parabola(fx):  # 2 segments' worth 10 % away
        return 2.0 * (np.log(fx / 500.0) / math.log(1.1)) ** 2

    est = _profiled(parabola)  # rules_out does not ask the focal confidence: the camera asks it first
    assert est.focal_worse_at(500.0) == pytest.approx(0.0, abs=0.01)
    assert est.focal_worse_at(392.0) == pytest.approx(parabola(392.0), rel=0.02)
    assert est.focal_worse_at(150.0) == 0.0 and est.focal_worse_at(1500.0) == 0.0  # beyond the profile
    assert est.rules_out(392.0) and est.rules_out(600.0)
    assert not est.rules_out(500.0 * 1.09)  # within RULE_OUT_FACTOR: as good as the estimate
    assert not est.rules_out(150.0)  # the profile says nothing there
    # measured from the best the profile found, not from the estimate
    shifted = _profiled(lambda fx: parabola(fx) - 3.0)
    assert shifted.focal_worse_at(500.0) == pytest.approx(0.0, abs=0.01)
    # too flat a profile, too wide a spread, or no estimate: nothing is ruled out
    flat = _profiled(lambda fx: np.minimum(parabola(fx), 0.9 * vanishing.RULE_OUT_MARGIN))
    assert not flat.rules_out(392.0)
    assert _profiled(parabola, focal_sd=vanishing.RULE_OUT_SD).rules_out(392.0)
    assert not _profiled(parabola, focal_sd=1.01 * vanishing.RULE_OUT_SD).rules_out(392.0)
    assert not _profiled(parabola, focal_sd=math.inf).rules_out(392.0)
    assert est.coherence == 1.0  # 90 % of the segments' length on three directions of 400 segments
    threshold = vanishing.RULE_OUT_COHERENCE
    assert dataclasses.replace(est, coherence=threshold).rules_out(392.0)
    assert not dataclasses.replace(est, coherence=0.99 * threshold).rules_out(392.0)
    assert not dataclasses.replace(est, focal_px=None).rules_out(392.0)


def test_seen_by_another_camera_keeps_the_vanishing_points_in_the_image():
    rot = _axis_rotation(0, -15.0) @ _axis_rotation(1, 20.0)
    est = vanishing.line_estimate(_fit(rot, [0.3, 0.3, 0.3]), 100)
    assert est.seen_by(500.0, 500.0, CX, CY) is est
    other = est.seen_by(600.0, 620.0, 300.0, 250.0)
    k_old = np.array([[500.0, 0, CX], [0, 500.0, CY], [0, 0, 1]])
    k_new = np.array([[600.0, 0, 300.0], [0, 620.0, 250.0], [0, 0, 1]])
    v_old, v_new = k_old @ est.down, k_new @ other.down
    assert np.allclose(v_old[:2] / v_old[2], v_new[:2] / v_new[2])
    assert np.linalg.norm(other.down) == pytest.approx(1.0) and other.down @ est.down > 0.9
    assert np.allclose(other.axes.T @ other.axes, np.eye(3), atol=1e-12)
    assert np.allclose(other.axes[:, 0], -other.down) and np.linalg.det(other.axes) == pytest.approx(1.0)
    h_old, h_new = k_old @ est.axes[:, 1], k_new @ other.axes[:, 1]
    # the horizontal made perpendicular to the new down stays on the old horizon's side
    assert h_old @ (k_new @ other.axes[:, 1]) != 0 and est.axes[:, 1] @ other.axes[:, 1] > 0.9
    assert other.focal_px == est.focal_px and other.down_confidence == est.down_confidence
    assert h_new.shape == (3,)
    d = est.to_dict()
    assert d["down"] == [round(float(x), 6) for x in est.down] and d["n_segments"] == 100
    assert d["focal_px"] == 500.0 and d["rms_px"] == 0.5
    # the vanishing points as unit homogeneous vectors, on the lines through the principal point
    vps = np.array(d["vanishing_points"])
    assert np.allclose(np.linalg.norm(vps, axis=1), 1.0, atol=1e-5)
    for v, col in zip(vps, rot.T, strict=True):
        assert np.allclose(np.cross(v, k_old @ col), 0.0, atol=1e-3 * np.linalg.norm(k_old @ col))


# ---- lines -------------------------------------------------------------------------------------------


def _drawing(w=640, h=480):
    img = np.full((h, w), 40, np.uint8)
    cv2.line(img, (100, 100), (500, 180), 230, 3, cv2.LINE_AA)
    cv2.line(img, (200, 400), (260, 250), 230, 3, cv2.LINE_AA)
    return img


@pytest.mark.parametrize("k", [2, 3])
def test_a_block_enlarged_image_has_the_segments_of_the_small_one_about_pixel_centres(k):
    small = _drawing()
    big = np.kron(small, np.ones((k, k), np.uint8))  # each pixel a k x k block: shrunk back exactly
    s, b = lines_mod.detect_segments(small), lines_mod.detect_segments(big)
    assert len(s) >= 2 and s.shape == b.shape
    assert np.allclose(b, s * k + (k - 1) / 2, atol=1e-4)
    # an RGB image of the same grey: the same segments
    assert np.allclose(lines_mod.detect_segments(np.dstack([big] * 3)), b, atol=1e-4)
    # the working size: max_side_px 320 shrinks the small image twice
    half = lines_mod.detect_segments(small, max_side_px=320)
    assert np.allclose(half, lines_mod.detect_segments(small[::2, ::2] * 0 + cv2.resize(small, (320, 240),
                       interpolation=cv2.INTER_AREA)) * 2 + 0.5, atol=1e-4)  # fmt: skip


def test_short_and_border_segments_are_dropped_and_the_longest_come_first():
    img = np.full((480, 640), 40, np.uint8)
    for p, q in [
        ((200, 100), (215, 100)),  # 15 px < 3 % of the 800 px diagonal: dropped
        ((200, 200), (240, 200)),  # 40 px: kept
        ((100, 300), (500, 300)),  # the longest
        ((100, 5), (500, 5)),  # along the top border (12 px band): dropped
        ((100, 475), (500, 475)),  # bottom
        ((5, 100), (5, 400)),  # left
        ((635, 100), (635, 400)),  # right
        ((320, 3), (320, 150)),  # from the border inwards: kept
        ((3, 420), (150, 420)),  # from the left border
        ((636, 60), (480, 60)),  # from the right border
        ((560, 476), (560, 330)),  # from the bottom border
        ((330, 15), (600, 15)),  # parallel to the top, but beyond the band (12 px of the short side)
    ]:
        cv2.line(img, p, q, 230, 2, cv2.LINE_AA)
    segs = lines_mod.detect_segments(img)
    length = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1])
    assert np.all(np.diff(length) <= 0) and length[0] > 380 and length.min() >= 24
    mid = (segs[:, :2] + segs[:, 2:]) / 2
    near = lambda x, y: np.any(np.hypot(mid[:, 0] - x, mid[:, 1] - y) < 6)  # noqa: E731 - a short helper
    assert near(300, 300) and near(220, 200) and near(320, 76)
    assert near(76, 420) and near(558, 60) and near(560, 403)
    # both edges of the line 15 px from the top (LSD finds each side of a 2 px line, 1.8 px off)
    assert np.sum((np.abs(mid[:, 0] - 465) < 5) & (mid[:, 1] > 12) & (mid[:, 1] < 18)) == 2
    assert not near(207, 100)
    for x, y in ((300, 5), (300, 475), (5, 250), (635, 250)):
        assert not near(x, y), (x, y)
    assert lines_mod.detect_segments(img, min_length_fraction=0.01).shape[0] > len(segs)


def test_the_hough_fallback_finds_the_same_long_edges():
    grey = _drawing()
    segs = lines_mod._hough(grey, 24.0)
    length = np.hypot(segs[:, 2] - segs[:, 0], segs[:, 3] - segs[:, 1])
    assert len(segs) >= 2 and length.max() > 300 and length.min() >= 24
    assert lines_mod._hough(np.full((480, 640), 40, np.uint8), 24.0).shape == (0, 4)


def test_a_given_fx_or_fy_alone_means_the_focal_length_is_given():
    from tests.geometry.test_vanishing import render_room

    img, _ = render_room(500.0, -15.0, 0.0, 30.0)
    for fx, fy in ((500.0, None), (None, 500.0)):
        est = vanishing.estimate_from_lines(img, fx, fy)
        assert est.focal_px is None and est.focal_confidence == 0.0 and est.fit.focal_px == 500.0
    with pytest.raises(dataclasses.FrozenInstanceError):
        est.down_confidence = 1.0


def test_without_lsd_the_fast_line_detector_of_a_contrib_build_is_used(monkeypatch):
    found = np.array([[[10.0, 20.0, 300.0, 40.0]], [[50.0, 400.0, 60.0, 100.0]]], np.float32)

    class Detector:
        def __init__(self, out):
            self.out = out

        def detect(self, grey):
            assert grey.ndim == 2 and grey.dtype == np.uint8
            return self.out

    class Ximgproc:  # the part of opencv-contrib's cv2.ximgproc that is used
        out = found

        @classmethod
        def createFastLineDetector(cls):  # noqa: N802 - OpenCV's name
            return Detector(cls.out)

    monkeypatch.setattr(lines_mod, "_lsd", lambda grey: None)
    monkeypatch.setattr(cv2, "ximgproc", Ximgproc, raising=False)
    segs = lines_mod.detect_segments(np.full((480, 640), 40, np.uint8))
    assert np.allclose(segs, found.reshape(-1, 4)[[1, 0]])  # longest first (300 and 291 px long)
    Ximgproc.out = None  # found nothing: no segments, and no Hough fallback
    assert lines_mod.detect_segments(_drawing()).shape == (0, 4)
    # a build without the fast line detector: the Hough transform
    monkeypatch.setattr(cv2, "ximgproc", object(), raising=False)
    assert len(lines_mod.detect_segments(_drawing())) >= 2


@pytest.mark.parametrize(
    "bad",
    [
        np.zeros((48, 64, 4), np.uint8),
        np.zeros((48, 64), np.float32),
        np.zeros(64, np.uint8),
        np.zeros((4, 4, 4, 3)),
    ],
    ids=["rgba", "float", "1-d", "4-d"],
)
def test_images_that_are_not_uint8_grey_or_rgb_are_refused(bad):
    with pytest.raises(ValueError):
        lines_mod.detect_segments(bad)


def test_the_record_keeps_micro_radians_of_directions_and_four_digits_of_confidences():
    rot = _axis_rotation(0, -15.123456789) @ _axis_rotation(1, 20.987654321)
    fit = dataclasses.replace(_fit(rot, [0.31234567, 0.28765432, 0.2123456]), rms_px=0.123456789)
    est = dataclasses.replace(
        vanishing.line_estimate(fit, 100),
        focal_px=512.3456789,
        focal_confidence=0.87654321,
        down_confidence=0.45678912,
    )
    d = est.to_dict()
    assert d["down"] == [round(float(x), 6) for x in est.down] and d["down"] != [float(x) for x in est.down]
    assert d["down_confidence"] == 0.4568
    assert d["focal_px"] == 512.35 and d["focal_confidence"] == 0.8765 and d["rms_px"] == 0.123
    assert dataclasses.replace(est, focal_sd=0.0456789).to_dict()["focal_sd"] == 0.0457
    assert dataclasses.replace(est, focal_sd=math.inf).to_dict()["focal_sd"] is None  # JSON has no inf
    assert d["manhattan_frame"] == [[round(float(x), 6) for x in row] for row in est.axes]
    assert d["support"] == [round(s, 4) for s in est.support] and d["support"][0] == 0.2877
    vps = fit.vanishing_points()
    assert d["vanishing_points"] == [[round(float(x), 6) for x in v / np.linalg.norm(v)] for v in vps]


def test_a_sliver_of_an_image_has_no_segments():
    # 3 rows of 5000 columns: shrunk 8 times, nothing is left of it
    sliver = np.zeros((3, 5000), np.uint8)
    sliver[:, 2000:] = 255
    segs = lines_mod.detect_segments(sliver)
    assert segs.shape == (0, 4) and segs.dtype == np.float64

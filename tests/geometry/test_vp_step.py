"""The Gauss-Newton refinement of Manhattan frames (geometry/vp_model.py) one piece at a time: the
residuals' derivatives against central differences on segments that do not point exactly at their vanishing
points (where the derivative of the residual's denominator matters), and one refinement step against the
damped Gauss-Newton step computed here from complex-step derivatives, halved until the cost drops."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from cuboidcli.geometry import manhattan_vp as mvp
from cuboidcli.geometry import vp_model as vm
from tests.geometry.test_vp_edges import CX, CY, ROT, SIZE, synth_segments

SCALE = 640.0
THR = 1.5 / SCALE
DAMPING = 1e-6  # Levenberg's damping, a fraction of the trace of the normal matrix (docs/mutation.md)
HALVINGS = 4  # the full step and three halvings of it are tried


def _rotation_vector(rng, lo_deg, hi_deg):
    w = rng.normal(size=3)
    return w * math.radians(rng.uniform(lo_deg, hi_deg)) / np.linalg.norm(w)


@pytest.fixture(scope="module")
def offset():
    """75 segments at f = 500 px moved by 3 px (sd): l . v is far from 0 for their own vanishing points."""
    segs, _ = synth_segments(ROT, 500.0, per=(30, 25, 20), seed=11, noise=3.0)
    return vm.Segments(segs, CX, CY, SCALE)


def _own(rot, phi, lines, labels):
    """Each segment's residual (public ``residuals``) for the vanishing point ``labels`` picks."""
    r = vm.residuals(vm.vanishing_points(rot, phi, 1.0), lines)
    return np.take_along_axis(r, labels[None], axis=0)[0]


def _skew(w):
    return np.array([[0.0, -w[2], w[1]], [w[2], 0.0, -w[0]], [-w[1], w[0], 0.0]])


def _complex_step_jacobian(rot, phi, lines, labels, npar, h=1e-30):
    """d r / d (w, log phi) by complex steps: rot -> (I + i h [e_j]x) rot (a small rotation on the left,
    exact to first order), phi -> phi exp(i h). Exact to rounding, not to the finite-difference error."""
    cols = []
    for j in range(npar):
        if j < 3:
            e = np.zeros(3)
            e[j] = 1.0
            r = _own((np.eye(3) + 1j * h * _skew(e)) @ rot, phi + 0j, lines, labels)
        else:
            r = _own(rot + 0j, phi * np.exp(1j * h), lines, labels)
        cols.append(r.imag / h)
    return np.stack(cols, axis=-1)


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_residuals_derivatives_are_their_central_differences_off_the_vanishing_points(offset, seed):
    rng = np.random.default_rng(seed)
    rot = cv2.Rodrigues(_rotation_vector(rng, 2.0, 8.0))[0] @ ROT
    phi = 500.0 / SCALE * math.exp(rng.uniform(-0.3, 0.3))
    r, labels, jac = vm._linearise(rot[None], np.array([phi]), offset, 1.0, 4)
    all_r = np.abs(vm.residuals(vm.vanishing_points(rot, phi, 1.0), offset))
    np.testing.assert_array_equal(labels[0], all_r.argmin(axis=0))  # each segment's nearest
    np.testing.assert_allclose(r[0], _own(rot, phi, offset, labels[0]), rtol=1e-12, atol=1e-15)
    # the segments are not exact: the term of the denominator's derivative (l . v) matters
    assert np.median(np.abs(r[0]) / offset.half) > 1e-3
    eps = 1e-6
    for j in range(4):
        plus, minus = [], []
        for sign, out in ((1.0, plus), (-1.0, minus)):
            if j < 3:
                w = np.zeros(3)
                w[j] = sign * eps
                out.append(_own(cv2.Rodrigues(w)[0] @ rot, phi, offset, labels[0]))
            else:
                out.append(_own(rot, phi * math.exp(sign * eps), offset, labels[0]))
        numeric = (plus[0] - minus[0]) / (2 * eps)
        scale = np.abs(numeric).max()
        np.testing.assert_allclose(jac[0, :, j], numeric, rtol=0, atol=1e-7 * scale)
    # with three parameters the same columns, without log phi's
    _, _, jac3 = vm._linearise(rot[None], np.array([phi]), offset, 1.0, 3)
    np.testing.assert_array_equal(jac3, jac[..., :3])


def _expected_step(rot, phi, lines, free_focal, phi_range):
    """One step by hand: nearest vanishing points, Huber weights times lengths (left out beyond 3 thr), the
    damped Gauss-Newton step (J^T W J + DAMPING tr(J^T W J) I) dx = -J^T W r, the focal part kept within
    phi_range, then the step, its half, quarter and eighth tried in turn until the weighted cost (labels and
    weights of the start) drops. Returns (rot, phi, how many halvings it took or None if none lowered the
    cost, the cost changes of the tries and of one more halving, the start's cost)."""
    npar = 4 if free_focal else 3
    all_r = np.abs(vm.residuals(vm.vanishing_points(rot, phi, 1.0), lines))
    labels = all_r.argmin(axis=0)
    r = _own(rot, phi, lines, labels)
    w = lines.weight * np.where(np.abs(r) < THR, 1.0, THR / np.abs(r)) * (np.abs(r) < 3 * THR)
    jac = _complex_step_jacobian(rot, phi, lines, labels, npar)
    normal = jac.T @ (w[:, None] * jac)
    lam = DAMPING * np.trace(normal) + 1e-12
    dx = -np.linalg.solve(normal + lam * np.eye(npar), jac.T @ (w * r))
    if free_focal:
        dx[3] = min(max(dx[3], math.log(phi_range[0] / phi)), math.log(phi_range[1] / phi))
    cost0 = float(w @ r**2)
    changes = []
    for k in range(HALVINGS + 1):  # one try beyond the last, to tell the cases apart
        t = 0.5**k
        new_rot = cv2.Rodrigues(t * dx[:3])[0] @ rot
        new_phi = phi * math.exp(t * dx[3]) if free_focal else phi
        changes.append(float(w @ _own(new_rot, new_phi, lines, labels) ** 2) - cost0)
    for k in range(HALVINGS):
        if changes[k] < 0:
            t = 0.5**k
            new_phi = phi * math.exp(t * dx[3]) if free_focal else phi
            return cv2.Rodrigues(t * dx[:3])[0] @ rot, new_phi, k, changes, cost0
    return rot, phi, None, changes, cost0


@pytest.mark.parametrize("free_focal", [True, False])
def test_one_refinement_step_is_the_damped_gauss_newton_step_halved_until_the_cost_drops(offset, free_focal):
    # starts 1-30 degrees and up to a factor 2 in focal length off, some of them outside the focal range
    # (the step's focal part then brings them back to its edge): near ones take the full step, far ones
    # overshoot and are halved or kept
    rng = np.random.default_rng(5)
    starts, phis = [], []
    for i in range(160):
        starts.append(cv2.Rodrigues(_rotation_vector(rng, 1.0 if i < 40 else 10.0, 30.0))[0] @ ROT)
        phis.append(500.0 / SCALE * math.exp(rng.uniform(-0.7, 0.7)))
    phi_range = (0.5, 1.2)
    rot, phi = vm.refine_frames(
        np.array(starts), np.array(phis), offset, 1.0, THR, free_focal, phi_range, steps=1
    )
    seen = {}
    for b, (start, phi0) in enumerate(zip(starts, phis, strict=True)):
        want_rot, want_phi, k, changes, cost0 = _expected_step(start, phi0, offset, free_focal, phi_range)
        if min(abs(c) for c in changes) < 1e-9 * cost0:
            continue  # a tie of the acceptance test: either answer is right
        seen[k] = seen.get(k, 0) + 1
        if k is None:
            np.testing.assert_array_equal(rot[b], start)
            assert phi[b] == phi0
            if changes[HALVINGS] < 0:
                seen["kept, lower one halving on"] = seen.get("kept, lower one halving on", 0) + 1
        else:
            np.testing.assert_allclose(rot[b], want_rot, rtol=0, atol=1e-10)
            assert phi[b] == pytest.approx(want_phi, rel=1e-10)
    # every branch of the step control is taken: with a free focal length the full step, its half and its
    # quarter, none (and then once where one more halving would have lowered the cost)
    if free_focal:
        assert all(seen.get(k, 0) >= 1 for k in (0, 1, 2, None)), seen
        assert seen.get("kept, lower one halving on", 0) >= 1, seen
    else:
        assert seen.get(0, 0) >= 100 and seen.get(1, 0) >= 1, seen


# ---- manhattan_vp: the likelihood profile and the focal margin on the refinement --------------------------


def test_the_likelihood_profile_of_two_candidates_is_the_better_of_each_alone():
    # with two candidates both are refined at every focal length (the best two are), and the profile is
    # the best frame there: the lower of the two profiles each candidate gives alone
    segs, _ = synth_segments(ROT, 500.0, per=(20, 20, 20), seed=4)
    lines = vm.Segments(segs, CX, CY, SCALE)
    decoy = cv2.Rodrigues(np.array([0.5, -0.3, 0.4]))[0] @ ROT  # 40 degrees off
    phi_range = tuple(0.5 / math.tan(math.radians(a) / 2) for a in mvp.FOV_RANGE_DEG[::-1])
    fine, true_alone = mvp._likelihood_profile(ROT[None], lines, 1.0, THR, phi_range)
    _, decoy_alone = mvp._likelihood_profile(decoy[None], lines, 1.0, THR, phi_range)
    _, both = mvp._likelihood_profile(np.stack([decoy, ROT]), lines, 1.0, THR, phi_range)
    assert len(fine) == mvp.LIKELIHOOD_STEPS
    near = np.abs(np.log(fine * SCALE / 500.0)) < 0.2
    assert np.all(decoy_alone[near] > true_alone[near] + 5 * THR**2)  # the decoy is worse near the truth
    np.testing.assert_allclose(both, np.minimum(true_alone, decoy_alone), rtol=1e-9, atol=1e-12)


@pytest.mark.parametrize(("f", "seed", "noise", "exact"), [(500.0, 4, 0.0, True), (400.0, 2, 1.0, False)])
def test_the_focal_margin_is_the_best_frame_held_at_a_profile_focal_length_a_rival_factor_away(
    f, seed, noise, exact
):
    # the rivals are the profile's focal lengths (PROFILE_STEPS log-spaced over FOV_RANGE_DEG) at least
    # RIVAL_FACTOR from the fit's, each held: the true frame refined at each is one of the frames there, so
    # the margin is at most its best cost over the fit's (prior included), and on exact segments it is that
    segs, _ = synth_segments(ROT, f, per=(20, 20, 20), seed=seed, noise=noise)
    fit = mvp.fit_manhattan(segs, SIZE)
    lines = vm.Segments(segs, CX, CY, SCALE)
    phi = fit.focal_px / SCALE
    ends = [0.5 / math.tan(math.radians(a) / 2) for a in mvp.FOV_RANGE_DEG[::-1]]
    grid = np.geomspace(ends[0], ends[1], mvp.PROFILE_STEPS)
    far = grid[np.abs(np.log(grid / phi)) >= math.log(mvp.RIVAL_FACTOR)]
    rots, _ = vm.refine_frames(np.repeat(ROT[None], len(far), 0), far, lines, 1.0, THR, False, (0.2, 3.0), 30)
    held = vm.msac_cost(rots, far, lines, 1.0, THR) + mvp._prior(far, THR)
    at_fit = vm.msac_cost(fit.rotation, phi, lines, 1.0, THR) + mvp._prior(phi, THR)
    bound = float(held.min() - at_fit) / THR**2
    assert 5.0 < fit.focal_margin <= bound * (1 + 1e-4)
    if exact:
        assert fit.focal_margin == pytest.approx(bound, rel=1e-4)

"""The fused CPU scoring loop must equal the torch reference kernels."""

import numpy as np
import pytest
import torch

from cuboidcli.fitting.backend import NumbaBackend
from cuboidcli.fitting.scoring import ScoreParams, gains_torch
from cuboidcli.geometry import kernels as K
from cuboidcli.geometry.fused import cuboid_values, score_gains
from cuboidcli.geometry.rotations import axis_angle_to_matrix

TAU, BETA = 0.004, 5.0


def scene(n=1500, h=200, seed=0):
    g = torch.Generator().manual_seed(seed)
    pts = torch.stack(
        [
            torch.rand(n, generator=g) * 4 - 2,
            torch.rand(n, generator=g) * 3 - 1.5,
            torch.rand(n, generator=g) * 4 + 1.5,
        ],
        -1,
    ).double()
    c = pts[torch.randint(0, n, (h,), generator=g)] + torch.randn(h, 3, generator=g).double() * 0.1
    R = axis_angle_to_matrix(torch.randn(h, 3, generator=g).double())
    a = torch.rand(h, 3, generator=g).double() * 1.0 + 0.01
    # a state with occluded (negative), inlier and zero points
    state = K.oai_of_set(pts, c[:3], a[:3], R[:3], TAU, BETA, 2 * TAU)
    return pts, c, a, R, state


@pytest.mark.parametrize("oai", [True, False])
def test_values_and_gains_match_reference(oai):
    pts, c, a, R, state = scene()
    assert (state < 0).sum() > 50 and (state > 0.5).sum() > 10
    sp = ScoreParams(TAU, BETA, 2 * TAU, oai)
    ref = gains_torch(pts, c, a, R, state, sp).numpy()
    got = score_gains(pts.numpy(), c.numpy(), a.numpy(), R.numpy(), state.numpy(), TAU, BETA, 2 * TAU, oai)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-6)
    if oai:
        vref = K.oai_per_cuboid(pts, c, a, R, TAU, BETA, 2 * TAU).numpy()
        np.testing.assert_allclose(
            cuboid_values(pts.numpy(), c.numpy(), a.numpy(), R.numpy(), TAU, BETA, 2 * TAU), vref, atol=1e-12
        )


def test_pruning_is_exact_for_the_winner():
    pts, c, a, R, state = scene(seed=3)
    args = (pts.numpy(), c.numpy(), a.numpy(), R.numpy(), state.numpy(), TAU, BETA, 2 * TAU)
    full = score_gains(*args)
    thr = np.sort(full)[-5]
    pruned = score_gains(*args, prune_below=thr)
    kept = np.isfinite(pruned)
    assert kept.sum() >= 5 and (~kept).sum() > 100
    np.testing.assert_allclose(pruned[kept], full[kept], rtol=1e-12)
    assert (full[~kept] < thr).all()
    assert pruned.argmax() == full.argmax()


def test_select_best_exact_and_fast_path():
    pts, c, a, R, state = scene(seed=4)
    sp = ScoreParams(TAU, BETA, 2 * TAU)
    ref = gains_torch(pts, c, a, R, state, sp).numpy()
    best, gain, _ = NumbaBackend().select_best(
        pts.float(), c.float(), a.float(), R.float(), state, sp, torch.Generator().manual_seed(0)
    )
    assert best == ref.argmax() and gain == pytest.approx(ref.max(), rel=1e-5)
    best2, gain2, g2 = NumbaBackend().select_best(
        pts.float(),
        c.float(),
        a.float(),
        R.float(),
        state,
        sp,
        torch.Generator().manual_seed(0),
        prescore_points=300,
        rescore_top=32,
    )
    assert np.isfinite(g2.numpy()).sum() == 32
    assert gain2 == pytest.approx(ref[best2], rel=1e-5)


def test_large_tau_c_of_the_training_schedule():
    # tau_c up to 1 m^2 (the start of the training schedule) must not overflow
    pts, c, a, R, state = scene(n=300, h=20, seed=6)
    sp = ScoreParams(TAU, BETA, 1.0)
    ref = gains_torch(pts, c, a, R, state, sp).numpy()
    got = score_gains(pts.numpy(), c.numpy(), a.numpy(), R.numpy(), state.numpy(), TAU, BETA, 1.0)
    np.testing.assert_allclose(got, ref, rtol=1e-9, atol=1e-6)


def test_occluding_sides_are_the_reference_occluders_and_their_distances():
    """The shared helper of the values loop and the refinement: the sides on a point's line of sight
    (chi_o, Eq. 6) and the point's squared distance to each, as the torch kernels compute them."""
    from cuboidcli.geometry.inlier import occluding_sides

    pts, c, a, R, _ = scene(n=300, h=12, seed=9)
    local = K.to_local(pts, c, R)
    chi = K.occlusion_indicator(local, a, K.camera_local(c, R))
    d2 = K.side_sq_distances(local, a)
    cam = K.camera_local(c, R).numpy()
    excess = (local.abs() - a[:, None]).clamp_min(0).square().numpy()
    found, twice = 0, 0
    for h in range(c.shape[0]):
        for i in range(pts.shape[0]):
            occ_in, ax_in, sg_in, d_in, occ_out, ax_out, sg_out, d_out = occluding_sides(
                *local[h, i].tolist(), *a[h].tolist(), *cam[h].tolist(), *excess[h, i].tolist()
            )
            sides = {}
            if occ_in:
                sides[2 * ax_in + (sg_in < 0)] = d_in
            if occ_out:
                sides[2 * ax_out + (sg_out < 0)] = d_out
            assert set(sides) == set(chi[h, i].nonzero().flatten().tolist()), (h, i)
            for side, d in sides.items():
                assert d == pytest.approx(float(d2[h, i, side]), abs=1e-12)
            found += len(sides)
            twice += len(sides) == 2
    assert found > 200 and twice > 20  # many occluded pairs, some by two sides

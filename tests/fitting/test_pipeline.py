"""End to end: render known boxes, fit, and check the abstraction explains the scene."""

import numpy as np
import pytest
import torch

from cuboidcli.cuboid import stack_cuboids
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.prepare import prepare_points
from cuboidcli.geometry.kernels import cuboid_sq_distance, inlier_fn, oa_sq_distance, oai_of_set, to_local
from tests.conftest import fit_named, simple_room


def joint_values(depth, camera, cuboids, config: FitConfig, occlusion_aware: bool) -> torch.Tensor:
    """Per fitting point: f_OAI of the cuboid set (Sec. 3.2.4), or the plain soft inlier of its nearest
    cuboid, computed with the reference kernels (N,)."""
    points = torch.from_numpy(prepare_points(depth, camera, config.step_for(*depth.shape)).points).double()
    c, a, R = stack_cuboids(cuboids, torch.float64)
    if occlusion_aware:
        return oai_of_set(points, c, a, R, config.tau_sq_m2, config.beta, config.tau_c)
    d_sq = cuboid_sq_distance(to_local(points, c, R), a)
    return inlier_fn(d_sq, config.tau_sq_m2, config.beta).amax(0)


def test_render_then_fit_recovers_simple_room(room_depth, nyu_camera):
    from cuboidcli.evaluation.coverage import coverage_mask

    depth, _ = room_depth
    config = FitConfig(seed=0)
    cuboids, info = fit_named(depth, nyu_camera, config)
    assert 3 <= len(cuboids) <= 8
    assert info.gains == [c.inlier_gain for c in cuboids]
    assert all(g > info.theta for g in info.gains)
    # each gain is what its cuboid added to the occlusion-aware inlier count: they sum to the count of the set
    count = joint_values(depth, nyu_camera, cuboids, config, occlusion_aware=True).sum().item()
    assert sum(info.gains) == pytest.approx(count, rel=1e-6)
    assert count > 0.9 * info.n_points
    covered = coverage_mask(nyu_camera, cuboids)
    pts = nyu_camera.backproject(depth).reshape(-1, 3)
    sel = covered.reshape(-1) & (pts[:, 2] > 0)
    assert sel.mean() > 0.5
    c, a, R = stack_cuboids(cuboids, torch.float64)
    oa = oa_sq_distance(torch.from_numpy(pts[sel]), c, a, R).sqrt()
    assert oa.mean().item() < 0.02  # metres: the paper's "OA covered" metric
    # most fitting points are explained by some cuboid, few are occluded
    lab = info.assignment
    valid = lab > -3
    assert (lab[valid] >= 0).mean() > 0.7
    assert (lab[valid] == -2).mean() < 0.05
    assert set(info.timing_s) >= {"prepare", "sample", "solve", "score", "update", "total"}


def test_fit_is_deterministic_for_a_seed(room_depth, nyu_camera):
    depth, _ = room_depth
    cfg = FitConfig(seed=7, hypotheses=512)
    a, _ = fit_named(depth, nyu_camera, cfg)
    b, _ = fit_named(depth, nyu_camera, cfg)
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        np.testing.assert_array_equal(x.center, y.center)
        np.testing.assert_array_equal(x.rotation, y.rotation)


def test_stopping_criterion_and_max_cuboids(room_depth, nyu_camera):
    depth, _ = room_depth
    cubs, info = fit_named(depth, nyu_camera, FitConfig(hypotheses=256, max_cuboids=2, theta=-1e9))
    assert len(cubs) == 2 and info.stop_reason == "max_cuboids"
    # a huge theta rejects everything: no cuboid is ever reported below the threshold
    cubs, info = fit_named(depth, nyu_camera, FitConfig(hypotheses=256, theta=3000.0))
    assert cubs == [] and info.stop_reason == "gain_below_theta" and info.rejected_gain < 3000.0
    assert info.batches and info.batches[0] >= 1
    # a theta above the number of points: nothing can reach it, the step stops without drawing
    cubs, info = fit_named(depth, nyu_camera, FitConfig(hypotheses=256, theta=1e6))
    assert cubs == [] and info.batches == [0] and info.rejected_gain is None


def test_fitting_grid_excludes_invalid_depth(nyu_camera):
    depth = np.full((480, 640), 2.0, dtype=np.float32)
    depth[:, :320] = 0.0
    depth[0, 328] = np.nan
    prep = prepare_points(depth, nyu_camera, 8)
    assert prep.grid.shape == (60, 80)
    assert prep.points.shape[0] == 60 * 40 - 1
    assert np.isfinite(prep.points).all() and (prep.points[:, 2] == 2.0).all()


def test_sequential_sampler_and_plain_inlier_baseline(room_depth, nyu_camera):
    depth, _ = room_depth
    seq, _ = fit_named(depth, nyu_camera, FitConfig(hypotheses=256, sampler="sequential"))
    config = FitConfig(hypotheses=256, occlusion_aware=False, max_cuboids=3, refine=False)
    plain, info = fit_named(depth, nyu_camera, config)
    assert len(seq) >= 1 and len(plain) >= 1
    # without OAI nothing is ever marked occluded
    assert (info.assignment != -2).all()
    # the gains are plain inlier counts: they sum to the plain count of the set, not to its occlusion-aware
    # count; the plain baseline's boxes hide many points (the paper's point about no-OAI fits)
    plain_count = joint_values(depth, nyu_camera, plain, config, occlusion_aware=False).sum().item()
    oai_count = joint_values(depth, nyu_camera, plain, config, occlusion_aware=True).sum().item()
    assert sum(info.gains) == pytest.approx(plain_count, rel=1e-6)
    assert oai_count < plain_count - 0.1 * info.n_points
    assert len(simple_room()) == 5


def test_the_estimator_warms_up_the_parts_it_is_given(room_depth, nyu_camera):
    """A fit on the CPU asks its solver and its sampler to compile their own kernels (``warm_up``) before
    it times anything; a part without the method has nothing to compile."""
    from cuboidcli.fitting.pipeline import fit_depth, warm_up_parts
    from cuboidcli.sampling import SequentialSampler
    from cuboidcli.solvers.numerical import NumericalSolver

    calls = []

    class Solver(NumericalSolver):
        def warm_up(self) -> None:
            calls.append("solver")
            super().warm_up()

    class Sampler(SequentialSampler):
        def warm_up(self) -> None:
            calls.append("sampler")
            super().warm_up()

    config = FitConfig(hypotheses=64, max_cuboids=1)
    fit_depth(room_depth[0], nyu_camera, config, solver=Solver(), sampler=Sampler())
    assert calls == ["solver", "sampler"]
    calls.clear()
    warm_up_parts(None, object(), Sampler())
    assert calls == ["sampler"]

"""Neural cuboid solver: network, checkpoints, synthetic data and pre-training (tiny random nets, CPU)."""

from __future__ import annotations

import json

import pytest
import torch

from cuboidcli.geometry.kernels import SIDE_AXIS, SIDE_SIGN
from cuboidcli.learn.solver_train import (
    SolverTrainConfig,
    set_sq_distances,
    solver_loss,
    train_solver,
)
from cuboidcli.nets.checkpoint import checkpoint_dict, parameter_count
from cuboidcli.nets.solver import SolverNet, SolverNetConfig
from cuboidcli.solvers.base import SizeBounds
from cuboidcli.solvers.neural import NeuralSolver, load_solver_net
from cuboidcli.solvers.synthetic import SyntheticConfig, sample_batch, seeded_batch, side_weights

TINY = SolverNetConfig(width=16, layers=1, heads=2, ff=32)


pytestmark = pytest.mark.usefixtures("one_thread")


def tiny_net(seed: int = 0) -> SolverNet:
    torch.manual_seed(seed)
    return SolverNet(TINY).eval()


def some_sets(n: int = 33, seed: int = 1) -> torch.Tensor:
    return seeded_batch(n, SyntheticConfig(), seed).points


def test_output_shapes_bounds_and_rotations():
    net = tiny_net()
    # Realistic sets plus far-off, huge and collapsed sets: the heads must stay in range regardless.
    x = torch.cat([some_sets(), 50.0 * torch.randn(4, 6, 3), torch.zeros(2, 6, 3) + 3.0])
    with torch.inference_mode():
        centers, half, rot = net(x)
    n = x.shape[0]
    assert centers.shape == (n, 3) and half.shape == (n, 3) and rot.shape == (n, 3, 3)
    assert bool((half >= TINY.a_min).all()) and bool((half <= TINY.a_max).all())
    eye = torch.eye(3).expand(n, 3, 3)
    assert torch.allclose(rot.transpose(1, 2) @ rot, eye, atol=1e-5)
    assert torch.allclose(torch.linalg.det(rot), torch.ones(n), atol=1e-5)
    # The translation head is tanh * a_max around the mean of the points.
    assert bool(((centers - x.mean(1)).abs() <= TINY.a_max + 1e-5).all())


def test_permutation_invariance_and_determinism():
    net = tiny_net()
    x = some_sets()
    perm = torch.randperm(6, generator=torch.Generator().manual_seed(3))
    with torch.inference_mode():
        a = net(x)
        b = net(x[:, perm])
        c = net(x)
    for u, v, w in zip(a, b, c, strict=True):
        assert torch.allclose(u, v, atol=1e-5)
        assert torch.equal(u, w)


def test_config_round_trip_and_parameter_count():
    cfg = SolverNetConfig(width=32, layers=3, heads=4, ff=48, a_min=0.01, a_max=3.0, input_scale=0.25)
    assert SolverNetConfig.from_dict(json.loads(json.dumps(cfg.to_dict()))) == cfg
    with pytest.raises(ValueError):
        SolverNetConfig.from_dict({**cfg.to_dict(), "dropout": 0.1})
    assert parameter_count(SolverNet(cfg)) > parameter_count(SolverNet(TINY))


def test_checkpoint_round_trip(tmp_path):
    net = tiny_net(5)
    path = tmp_path / "solver.pt"
    torch.save(checkpoint_dict(net, {"iteration": 7}), path)
    blob = torch.load(path, weights_only=True)
    assert blob["config"] == TINY.to_dict() and blob["meta"] == {"iteration": 7}
    loaded = load_solver_net(path)
    assert not loaded.training and loaded.config == TINY
    x = some_sets()
    with torch.inference_mode():
        for u, v in zip(net(x), loaded(x), strict=True):
            assert torch.equal(u, v)


def test_neural_solver_protocol(tmp_path):
    path = tmp_path / "solver.pt"
    torch.save(checkpoint_dict(tiny_net()), path)
    solver = NeuralSolver(path)
    assert solver.name == "neural" and solver.bounds == SizeBounds(TINY.a_min, TINY.a_max)
    x = some_sets(600).double()  # more than one forward chunk
    centers, half, rot = solver(x)
    assert centers.dtype == torch.float64 and rot.shape == (600, 3, 3)
    with torch.inference_mode():
        ref = solver.net(x.float())
    assert torch.allclose(centers.float(), ref[0], atol=1e-6)
    half.clamp_(0.1, 1.0)  # results are ordinary tensors, not inference tensors
    with pytest.raises(ValueError, match="trained for half-sizes"):
        NeuralSolver(path, bounds=SizeBounds(2.0, 30.0))
    with pytest.raises(FileNotFoundError):
        NeuralSolver(tmp_path / "missing.pt")
    with pytest.raises(TypeError, match="weights file or a loaded net"):
        NeuralSolver()  # the default weights are the factories' choice (cuboidcli.factories.make_solver)


def test_neural_solver_thread_pool_matches_serial():
    net = tiny_net(2)
    x = some_sets(1500)
    serial = NeuralSolver(net=net, threads=1)(x)
    pooled = NeuralSolver(net=net, threads=2)(x)
    assert torch.get_num_threads() == 1  # the call restores torch's thread setting
    for u, v in zip(serial, pooled, strict=True):
        assert torch.allclose(u, v, atol=1e-6)


def test_clean_points_lie_on_camera_facing_sides():
    cfg = SyntheticConfig().clean()
    batch = sample_batch(500, cfg, torch.Generator().manual_seed(11))
    assert batch.points.shape == (500, 6, 3) and bool(batch.inlier.all())
    sq = set_sq_distances(
        batch.points.double(), batch.centers.double(), batch.half_sizes.double(), batch.rotations.double()
    )
    assert float(sq.max()) < 1e-10
    assert float(batch.points[..., 2].min()) >= cfg.min_depth
    # Each point lies on the plane of its side, and the camera (origin) is on the outer side of that plane.
    local = torch.einsum(
        "bck,bkj->bcj", batch.points.double() - batch.centers.double()[:, None], batch.rotations.double()
    )
    axis = torch.tensor(SIDE_AXIS)[batch.sides]
    sign = torch.tensor(SIDE_SIGN, dtype=torch.float64)[batch.sides]
    on_axis = local.gather(-1, axis[..., None])[..., 0]
    a = batch.half_sizes.double()[:, None, :].expand_as(local).gather(-1, axis[..., None])[..., 0]
    assert torch.allclose(on_axis, sign * a, atol=1e-5)
    normal = torch.einsum(
        "bij,bcj->bci",
        batch.rotations.double(),
        torch.nn.functional.one_hot(axis, 3).double() * sign[..., None],
    )
    assert bool(((batch.points.double() * normal).sum(-1) < 0).all())
    weights = side_weights(batch.centers, batch.half_sizes, batch.rotations)
    assert bool((weights.gather(1, batch.sides) > 0).all())
    assert int((weights > 0).sum(-1).max()) <= 3


def test_noise_and_outliers_are_seeded_and_flagged():
    cfg = SyntheticConfig()
    a, b = seeded_batch(2000, cfg, 4), seeded_batch(2000, cfg, 4)
    assert torch.equal(a.points, b.points) and torch.equal(a.inlier, b.inlier)
    outlier_sets = (~a.inlier).any(1).float().mean()
    assert 0.12 < float(outlier_sets) < 0.18
    assert int((~a.inlier).sum(1).max()) == 1
    sq = set_sq_distances(a.points, a.centers, a.half_sizes, a.rotations)
    z, ray = a.points[..., 2], a.points.norm(dim=-1)
    # Noise moves a point along its viewing ray by N(0, sigma^2) in depth, sigma = noise_at_1m z^2, i.e. by
    # |dz| |p| / z in space: inliers stay within 6 sigma of that; outliers are far off.
    bound = 6 * cfg.noise_at_1m * z.square() * ray / z
    assert bool((sq.sqrt() <= bound + 1e-6)[a.inlier].all())
    assert float(sq[~a.inlier].sqrt().median()) > 0.05


def test_lr_schedule():
    cfg = SolverTrainConfig(iters=100, warmup=10, lr=1e-3, final_lr_ratio=0.1)
    assert cfg.lr_at(0, cfg.iters) == pytest.approx(1e-4)
    assert cfg.lr_at(9, cfg.iters) == pytest.approx(1e-3)
    assert cfg.lr_at(99, cfg.iters) == pytest.approx(1e-4, rel=1e-2)
    assert all(cfg.lr_at(i, cfg.iters) >= cfg.lr_at(i + 1, cfg.iters) for i in range(10, 99))
    # With a time budget the decay follows the budget when it runs ahead of the steps.
    assert cfg.lr_at(20, cfg.iters, time_fraction=1.0) == pytest.approx(1e-4)
    assert cfg.lr_at(20, cfg.iters, time_fraction=0.0) == cfg.lr_at(20, cfg.iters)
    assert cfg.lr_at(5, cfg.iters, time_fraction=0.9) == cfg.lr_at(5, cfg.iters)  # warm-up is by steps


def test_training_reduces_loss_on_a_fixed_batch():
    torch.manual_seed(0)
    net = SolverNet(TINY)
    batch = seeded_batch(64, SyntheticConfig(), 21)
    opt = torch.optim.Adam(net.parameters(), lr=1e-2)
    losses = []
    for _ in range(40):
        loss = solver_loss(net, batch.points, batch.inlier)
        opt.zero_grad()
        loss.backward()
        opt.step()
        losses.append(loss.item())
    assert losses[-1] < 0.5 * losses[0]


def _records(path):
    return [json.loads(line) for line in path.read_text().splitlines()]


def test_resume_continues_exactly(tmp_path):
    cfg = SolverTrainConfig(
        iters=6,
        batch=32,
        lr=3e-3,
        warmup=2,
        log_every=1,
        val_every=3,
        ckpt_every=3,
        val_sets=16,
        threads=1,
    )
    full = train_solver(cfg, TINY, tmp_path / "a")
    assert full["iteration"] == 6 and (tmp_path / "a" / "best.pt").is_file()
    resumed = train_solver(cfg, SolverNetConfig(), tmp_path / "b", resume=tmp_path / "a" / "step_0000003.pt")
    assert resumed["iteration"] == 6

    def losses(run):
        records = _records(tmp_path / run / "log.jsonl")
        return {r["iteration"]: r["loss_m2"] for r in records if r["event"] == "train"}

    a, b = losses("a"), losses("b")
    assert sorted(b) == [4, 5, 6]
    assert all(a[i] == b[i] for i in (4, 5, 6))
    sa = torch.load(tmp_path / "a" / "last.pt", weights_only=True)["state_dict"]
    sb = torch.load(tmp_path / "b" / "last.pt", weights_only=True)["state_dict"]
    assert all(torch.equal(sa[k], sb[k]) for k in sa)
    # The best weights are a plain inference checkpoint with the validation residuals in their meta.
    best = torch.load(tmp_path / "a" / "best.pt", weights_only=True)
    assert set(best) == {"config", "state_dict", "meta"} and "noisy" in best["meta"]["validation"]
    # ... written as solver_v2.pt too, so that the output folder works as --weights OUT
    from cuboidcli.solvers.neural import load_solver_net
    from cuboidcli.weights import resolve

    net = load_solver_net(resolve("solver", tmp_path / "a"), "cpu")
    assert all(torch.equal(t, best["state_dict"][k]) for k, t in net.state_dict().items())

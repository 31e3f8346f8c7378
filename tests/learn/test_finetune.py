"""End-to-end fine-tuning (cuboidcli.learn.finetune): gradients reach every network, runs write usable
weights, resume continues, bad settings are refused. Tiny networks on a 4-frame RGB-D dataset."""

import numpy as np
import pytest
import torch

from cuboidcli.camera import Camera
from cuboidcli.factories import load_learned_sampler
from cuboidcli.fitting.config import FitConfig
from cuboidcli.learn.finetune import DEPTH_NAME, SAMPLER_NAME, SOLVER_NAME, finetune
from cuboidcli.learn.finetune_config import FinetuneConfig
from cuboidcli.learn.finetune_data import load_scene
from cuboidcli.learn.finetune_loss import Nets, backproject_grid, predicted_grid, scene_loss
from cuboidcli.nets.checkpoint import checkpoint_dict
from cuboidcli.nets.sampler import SamplerNet, SamplerNetConfig
from cuboidcli.nets.solver import SolverNet, SolverNetConfig
from cuboidcli.solvers.implicit import polished
from cuboidcli.solvers.numerical import NumericalSolver
from tests.conftest import write_room_dataset

CAMERA = Camera.preset("nyu").scaled(0.25)  # 160x120


@pytest.fixture(scope="module")
def rgbd_dataset(tmp_path_factory):
    """Four frames of simple_room (3 train, 1 val) with depth and a shaded RGB image."""
    root = tmp_path_factory.mktemp("finetune_data")
    write_room_dataset(root, CAMERA, rgb=True)
    return root


@pytest.fixture(scope="module")
def weights(tmp_path_factory):
    """Tiny sampler (with the prior), solver and depth nets saved as the trainers would."""
    from cuboidcli.nets.depth import DepthNet, DepthNetConfig

    root = tmp_path_factory.mktemp("weights")
    torch.manual_seed(0)
    sampler = SamplerNet(SamplerNetConfig(width=16, blocks=1, upsample=2, prior="unexplained"))
    solver = SolverNet(SolverNetConfig(width=16, layers=1, heads=2, ff=32))
    depth = DepthNet(
        DepthNetConfig(channels=(4, 8, 8, 8, 8), input_height=64, input_width=80, canonical_focal_px=65.0)
    )
    torch.save(checkpoint_dict(sampler), root / "sampler.pt")
    torch.save(checkpoint_dict(solver), root / "solver.pt")
    torch.save(checkpoint_dict(depth), root / "depth.pt")
    return root


def _nets(weights, rgb: bool, neural: bool) -> Nets:
    from cuboidcli.learn.finetune_loss import load_nets

    cfg = FinetuneConfig(rgb=rgb, solver="neural" if neural else "numerical")
    return load_nets(cfg, weights / "sampler.pt", weights / "solver.pt", weights / "depth.pt")


def _grads(module) -> list[float]:
    return [float(p.grad.abs().sum()) if p.grad is not None else 0.0 for p in module.parameters()]


def test_depth_input_gradients_reach_sampler_and_neural_solver(rgbd_dataset, weights):
    from cuboidcli.io.dataset import list_frames

    nets = _nets(weights, rgb=False, neural=True)
    scene = load_scene(list_frames(rgbd_dataset)[0], 4, None)
    # an untrained tiny solver makes only occluding boxes: without a wide clamp every task loss would sit at
    # the clamp and both sets would tie (zero policy gradient), which is right but tests nothing
    cfg = FinetuneConfig(instances=2, hypotheses=8, loss_clamp=100.0)
    loss, records = scene_loss(nets, scene, cfg, FitConfig(), None, torch.Generator().manual_seed(0))
    loss.backward()
    assert len(records) == 2 and np.isfinite(loss.item())
    assert sum(_grads(nets.sampler)) > 0
    assert sum(_grads(nets.sampler.map_head)) > 0  # the policy gradient reaches the maps
    solver_grads = _grads(nets.solver)
    assert sum(solver_grads) > 0 and np.isfinite(solver_grads).all()


def test_a_descent_step_on_the_loss_makes_the_solver_better(rgbd_dataset, weights):
    """The loss points the right way: one gradient-descent step of the neural solver on the fine-tuning
    loss raises the occlusion-aware inlier counts of its cuboids, measured with the kernels on fixed
    minimal sets (flipping the sign of the loss or of its task term makes them fall)."""
    from cuboidcli.geometry.kernels import oai_per_cuboid
    from cuboidcli.io.dataset import list_frames

    nets = _nets(weights, rgb=False, neural=True)
    scene = load_scene(list_frames(rgbd_dataset)[0], 4, None)
    fit = FitConfig()
    z = scene.z_points.float()
    sets = z[torch.randint(0, z.shape[0], (256, 6), generator=torch.Generator().manual_seed(5))]

    def inlier_counts() -> tuple[float, float]:
        with torch.no_grad():
            c, a, r = nets.solver(sets)
            counts = oai_per_cuboid(z, c, a, r, fit.tau_sq_m2, fit.beta, fit.tau_c).sum(1)
        return float(counts.max()), float(counts.mean())

    before = inlier_counts()
    opt = torch.optim.SGD(nets.solver.parameters(), lr=0.05)  # the sampler stays fixed
    cfg = FinetuneConfig(instances=1, hypotheses=32, loss_clamp=100.0)
    loss, _ = scene_loss(nets, scene, cfg, fit, None, torch.Generator().manual_seed(0))
    loss.backward()
    opt.step()
    after = inlier_counts()
    assert after[0] > before[0] + 100.0 and after[1] > before[1] + 1000.0, (before, after)


@pytest.mark.parametrize("neural", [False, True])
def test_rgb_gradients_reach_the_depth_network(rgbd_dataset, weights, neural):
    """Through the implicit-function gradients of the numerical solver, or through the neural solver."""
    from cuboidcli.io.dataset import list_frames

    nets = _nets(weights, rgb=True, neural=neural)
    scene = load_scene(list_frames(rgbd_dataset)[0], 4, (64, 80))
    numerical = None if neural else polished(NumericalSolver())
    cfg = FinetuneConfig(
        rgb=True, solver="neural" if neural else "numerical", instances=2, hypotheses=8, loss_clamp=100.0
    )
    loss, _ = scene_loss(nets, scene, cfg, FitConfig(), numerical, torch.Generator().manual_seed(1))
    loss.backward()
    depth_grads = _grads(nets.depth)
    assert sum(depth_grads) > 0 and np.isfinite(depth_grads).all()
    assert sum(_grads(nets.sampler)) > 0


def test_predicted_points_follow_the_camera(rgbd_dataset, weights):
    """The grid of the depth prediction back-projects with the camera like the fitting points do."""
    from cuboidcli.io.dataset import list_frames

    nets = _nets(weights, rgb=True, neural=True)
    frame = list_frames(rgbd_dataset)[1]
    scene = load_scene(frame, 4, (64, 80))
    grid = predicted_grid(nets.depth, scene)
    assert grid.shape == scene.grid_shape
    # the true depth on the grid back-projects to exactly the scene's true points
    pts = backproject_grid(scene.depth_grid, scene)
    torch.testing.assert_close(pts, scene.z_points, atol=1e-5, rtol=1e-5)


def _tiny(**kw) -> FinetuneConfig:
    base = dict(epochs=1, batch=2, hypotheses=8, instances=2, grid_step=4, val_hypotheses=32, lr=1e-3)
    return FinetuneConfig(**{**base, **kw})


def test_finetune_writes_weights_and_resumes(tmp_path, rgbd_dataset, weights):
    kw = dict(
        sampler_weights=weights / "sampler.pt",
        solver_weights=weights / "solver.pt",
        depth_weights=weights / "depth.pt",
    )
    out = tmp_path / "run"
    final = finetune(_tiny(rgb=True, validate_initial=False), rgbd_dataset, out, **kw)
    assert final["epochs_done"] == 1
    for name in (SAMPLER_NAME, SOLVER_NAME, DEPTH_NAME, "last.pt", "config.json"):
        assert (out / name).is_file(), name
    for name in (SAMPLER_NAME, SOLVER_NAME, DEPTH_NAME):
        ckpt = torch.load(out / name, weights_only=True)
        assert set(ckpt) >= {"config", "state_dict", "meta"}
    # the fine-tuned depth network differs from its start; the files load where fit loads them
    from cuboidcli.depth.estimator import BuiltinDepthEstimator
    from cuboidcli.solvers.neural import NeuralSolver

    start = torch.load(weights / "depth.pt", weights_only=True)["state_dict"]
    tuned = torch.load(out / DEPTH_NAME, weights_only=True)["state_dict"]
    assert any(not torch.equal(start[k], tuned[k]) for k in start)
    BuiltinDepthEstimator(out / DEPTH_NAME)
    load_learned_sampler(out)
    NeuralSolver(out / SOLVER_NAME)

    # two epochs straight == one epoch, then resume for the second
    finetune(_tiny(rgb=True, epochs=2, validate_initial=False), rgbd_dataset, tmp_path / "a", **kw)
    finetune(_tiny(rgb=True, epochs=1, validate_initial=False), rgbd_dataset, tmp_path / "b", **kw)
    finetune(_tiny(rgb=True, epochs=2), rgbd_dataset, tmp_path / "b", resume=tmp_path / "b" / "last.pt", **kw)
    a = torch.load(tmp_path / "a" / "last.pt", weights_only=True)
    b = torch.load(tmp_path / "b" / "last.pt", weights_only=True)
    assert a["epoch"] == b["epoch"] == 2
    for net in ("sampler", "solver", "depth"):
        for k, v in a["nets"][net].items():
            torch.testing.assert_close(v, b["nets"][net][k], rtol=0, atol=0)


def test_bad_settings_are_refused(tmp_path, rgbd_dataset):
    with pytest.raises(ValueError, match="numerical"):
        FinetuneConfig(solver="numerical")  # depth input + numerical solver has nothing to fine-tune
    with pytest.raises(ValueError, match="samples_k"):
        FinetuneConfig(samples_k=1)
    with pytest.raises(ValueError, match="solver"):
        FinetuneConfig(solver="magic")
    with pytest.raises(FileNotFoundError, match="sampler weights"):
        finetune(_tiny(), rgbd_dataset, tmp_path / "x", sampler_weights=tmp_path / "none.pt")


def test_cli_reports_errors(tmp_path):
    from typer.testing import CliRunner

    from cuboidcli.cli.main import app

    runner = CliRunner()
    res = runner.invoke(app, ["train", "finetune", str(tmp_path / "missing")])
    assert res.exit_code == 2 and "not found" in res.output
    (tmp_path / "data").mkdir()
    res = runner.invoke(app, ["train", "finetune", str(tmp_path / "data"), "--solver", "numerical"])
    assert res.exit_code == 2 and "numerical" in res.output

"""Training of the sampling-weight network (cuboidcli.learn.sampler_loss / sampler_train), tiny and fast."""

import json
import math

import numpy as np
import pytest
import torch

from cuboidcli.camera import Camera
from cuboidcli.factories import load_learned_sampler
from cuboidcli.fitting.prepare import prepare_points
from cuboidcli.geometry.kernels import oai_per_cuboid
from cuboidcli.learn.sampler_config import SamplerTrainConfig
from cuboidcli.learn.sampler_loss import (
    LossParams,
    correlation_loss,
    correlation_matrix,
    draw_sets,
    entropy,
    entropy_loss,
    inlier_masking_loss,
    instance_loss,
    occlusion_threshold,
    set_log_prob,
)
from cuboidcli.learn.sampler_train import train_sampler, train_scene
from cuboidcli.nets.sampler import SamplerNet, SamplerNetConfig
from cuboidcli.sampling import SamplingContext
from cuboidcli.sampling.learned import grid_inputs
from cuboidcli.solvers.numerical import NumericalSolver
from cuboidcli.weights import FILES
from tests.conftest import simple_room, write_room_dataset

TINY = SamplerNetConfig(width=16, blocks=1, upsample=2)
SAMPLER_FILE = FILES["sampler"]
#: Only the policy-gradient term: every regulariser off.
PG_ONLY = LossParams(hypotheses=32, kappa_corr=0.0, kappa_entropy=0.0, kappa_im=0.0)


@pytest.fixture(scope="module")
def camera() -> Camera:
    return Camera.preset("nyu").scaled(0.25)  # 160x120


@pytest.fixture(scope="module")
def prep(camera):
    """simple_room at 160x120; every 4th pixel -> a 30x40 fitting grid."""
    from cuboidcli.synth.render import render_boxes

    depth, _ = render_boxes(simple_room(), camera)
    return prepare_points(depth, camera, 4).as_tensors()


def _net_output(net, prep, state=None):
    n = prep.points.shape[0]
    state = torch.zeros(n) if state is None else state
    ctx = SamplingContext(prep.points, prep.grid.index, prep.grid.shape, prep.grid.depth, state, 0)
    out = net(*grid_inputs(ctx))
    return out.log_p[0].flatten(1)[:, prep.grid.index], out.log_q[0]


# ---- regularisers and schedule on hand-built inputs -------------------------------------------------


def test_correlation_of_identical_and_disjoint_maps():
    g = torch.Generator().manual_seed(0)
    m = torch.rand(50, generator=g)
    p = torch.stack([m, m]) / m.sum()
    torch.testing.assert_close(correlation_matrix(p), torch.ones(2, 2))
    torch.testing.assert_close(correlation_loss(p), torch.tensor(2.0))  # sum over ordered pairs i != j
    same4 = torch.stack([m] * 4) / m.sum()
    torch.testing.assert_close(correlation_loss(same4), torch.tensor(12.0))  # Q (Q - 1)
    half = torch.zeros(2, 50)
    half[0, :25], half[1, 25:] = 1 / 25, 1 / 25
    torch.testing.assert_close(correlation_matrix(half)[0, 1], torch.tensor(-1.0))
    torch.testing.assert_close(correlation_loss(half), torch.tensor(-2.0))  # the paper rewards this
    torch.testing.assert_close(correlation_loss(half, "positive"), torch.tensor(0.0))  # ours does not
    torch.testing.assert_close(correlation_loss(same4, "positive"), torch.tensor(12.0))
    with pytest.raises(ValueError, match="corr_mode"):
        correlation_loss(p, "negative")


def test_entropy_of_uniform_and_peaked_q():
    for q_count in (1, 2, 4):
        q = torch.full((q_count,), 1.0 / q_count)
        torch.testing.assert_close(entropy(q), torch.tensor(math.log(q_count)))
        torch.testing.assert_close(entropy_loss(q), torch.tensor(-math.log(q_count)))
    assert float(entropy(torch.tensor([1.0, 0.0, 0.0, 0.0]))) == 0.0


def test_inlier_masking_penalises_weight_on_explained_points():
    state = torch.tensor([1.0, 1.0, 0.0, 0.0, -2.0, -2.0])
    on_inliers = torch.tensor([[0.5, 0.5, 0.0, 0.0, 0.0, 0.0]])
    elsewhere = torch.tensor([[0.0, 0.0, 0.5, 0.5, 0.0, 0.0]])
    on_occluded = torch.tensor([[0.0, 0.0, 0.0, 0.0, 0.5, 0.5]])
    assert float(inlier_masking_loss(on_inliers, state)) == pytest.approx(2 / 6)
    assert float(inlier_masking_loss(elsewhere, state)) == 0.0
    assert float(inlier_masking_loss(on_occluded, state)) == 0.0  # occluded points are not "explained"


def test_occlusion_threshold_schedule():
    tau = 0.004
    assert occlusion_threshold(0, 25, tau) == pytest.approx(1.0)
    assert occlusion_threshold(25, 25, tau) == pytest.approx(tau)
    assert occlusion_threshold(10, 20, tau) == pytest.approx(0.5 * (1.0 + tau))
    values = [occlusion_threshold(e, 25, tau) for e in range(25)]
    assert values == sorted(values, reverse=True) and values[-1] > tau


def test_draws_follow_q_and_p():
    g = torch.Generator().manual_seed(0)
    p = torch.zeros(3, 10)
    p[0, :2], p[1, 5], p[2, 9] = 0.5, 1.0, 1.0
    maps, idx = draw_sets(p, torch.tensor([0.0, 1.0, 0.0]), 8, 6, g)
    assert torch.all(maps == 1) and torch.all(idx == 5)
    maps, idx = draw_sets(p, torch.tensor([0.5, 0.0, 0.5]), 64, 6, g)
    assert set(maps.tolist()) == {0, 2}
    assert torch.all(idx[maps == 0] < 2) and torch.all(idx[maps == 2] == 9)
    log_p = torch.log(p.clamp_min(1e-30))
    log_q = torch.log(torch.tensor([0.5, 0.0, 0.5]).clamp_min(1e-30))
    expected = 64 * math.log(0.5) + 6 * float((maps == 0).sum()) * math.log(0.5)
    assert float(set_log_prob(log_p, log_q, maps, idx)) == pytest.approx(expected)


# ---- the policy gradient ----------------------------------------------------------------------------


def test_policy_gradient_reaches_every_map_and_q(prep):
    """The research code lost the task gradient of the maps for Q > 1; here every map and q get one."""
    n = prep.points.shape[0]
    g = torch.Generator().manual_seed(0)
    map_logits = torch.randn(4, n, generator=g).requires_grad_(True)
    q_logits = torch.zeros(4, requires_grad=True)
    res = instance_loss(
        torch.log_softmax(map_logits, 1),
        torch.log_softmax(q_logits, 0),
        prep.points,
        torch.zeros(n, dtype=torch.float64),
        NumericalSolver(),
        PG_ONLY,
        torch.Generator().manual_seed(1),
    )
    assert res.maps_drawn == [0, 1, 2, 3]
    res.loss.backward()
    per_map = map_logits.grad.abs().sum(1)
    assert torch.all(per_map > 0), per_map
    assert q_logits.grad.abs().sum() > 0
    assert torch.isfinite(map_logits.grad).all()


def test_policy_gradient_reaches_every_map_head_of_the_net(prep):
    torch.manual_seed(0)
    net = SamplerNet(TINY)
    n = prep.points.shape[0]
    log_p, log_q = _net_output(net, prep)
    res = instance_loss(
        log_p, log_q, prep.points, torch.zeros(n, dtype=torch.float64), NumericalSolver(), PG_ONLY,
        torch.Generator().manual_seed(2),
    )  # fmt: skip
    res.loss.backward()
    # row j of the last 1x1 convolution produces map j only, row j of the FC layer q_j only
    assert torch.all(net.map_head.weight.grad.flatten(1).abs().sum(1) > 0)
    assert torch.all(net.q_head.weight.grad.abs().sum(1) > 0)


def test_a_few_steps_raise_the_expected_inlier_count(prep):
    """REINFORCE on one fixed scene: hypotheses drawn from the maps explain more points after training."""
    solver = NumericalSolver()
    n = prep.points.shape[0]

    def mean_gain(net) -> float:  # mean I_c / N over 512 hypotheses drawn with a fixed generator
        with torch.no_grad():
            log_p, log_q = _net_output(net, prep)
        maps, idx = draw_sets(log_p.exp(), log_q.exp(), 512, 6, torch.Generator().manual_seed(123))
        values = oai_per_cuboid(prep.points, *solver(prep.points[idx]), 0.004, 5.0, 1.0)
        return float(values.sum(1).mean()) / n

    torch.manual_seed(1)
    net = SamplerNet(TINY)
    opt = torch.optim.Adam(net.parameters(), lr=2e-2)
    gen = torch.Generator().manual_seed(1)
    before = mean_gain(net)
    losses = []
    for _ in range(30):
        opt.zero_grad()
        losses.append(train_scene(net, prep, solver, PG_ONLY, 1, gen, 1.0)[0]["expected_loss"])
        opt.step()
    after = mean_gain(net)
    assert after > before + 0.05, (before, after)
    assert np.mean(losses[-8:]) < np.mean(losses[:8])


# ---- the training loop: checkpoints, resume, CLI ----------------------------------------------------


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory, camera):
    """Four frames of simple_room seen from slightly shifted cameras: 3 train, 1 val."""
    root = tmp_path_factory.mktemp("sampler_data")
    write_room_dataset(root, camera)
    return root


def _tiny_config(**kw) -> SamplerTrainConfig:
    base = dict(epochs=2, batch=2, hypotheses=16, instances=2, grid_step=4, val_hypotheses=32, lr=1e-3)
    return SamplerTrainConfig(**{**base, **kw})


def _records(path, event):
    lines = (json.loads(line) for line in path.read_text().splitlines())
    return [r for r in lines if r["event"] == event]


def test_resume_continues_exactly(tmp_path, tiny_dataset):
    cfg = _tiny_config(validate_initial=False)
    train_sampler(cfg, tiny_dataset, tmp_path / "a", net_cfg=TINY)
    train_sampler(cfg, tiny_dataset, tmp_path / "b", net_cfg=TINY, stop_after_epoch=1)
    assert not (tmp_path / "b" / "epoch_002.pt").exists()
    train_sampler(cfg, tiny_dataset, tmp_path / "b", resume=tmp_path / "b" / "last.pt")

    steps_a = _records(tmp_path / "a" / "log.jsonl", "step")
    steps_b = _records(tmp_path / "b" / "log.jsonl", "step")
    assert len(steps_a) == len(steps_b) == 4  # 2 epochs x ceil(3 scenes / batch 2)
    for key in ("loss", "expected_loss", "best_gain", "scenes", "tau_c_sq_m2"):
        assert [r[key] for r in steps_a] == [r[key] for r in steps_b], key
    val_a = _records(tmp_path / "a" / "log.jsonl", "val")
    val_b = _records(tmp_path / "b" / "log.jsonl", "val")
    assert [r["mean_inlier_fraction"] for r in val_a] == [r["mean_inlier_fraction"] for r in val_b]
    state_a = torch.load(tmp_path / "a" / "last.pt", weights_only=True)
    state_b = torch.load(tmp_path / "b" / "last.pt", weights_only=True)
    for k, v in state_a["state_dict"].items():
        torch.testing.assert_close(v, state_b["state_dict"][k], rtol=0, atol=0)
    assert state_a["epoch"] == state_b["epoch"] == 2
    # the tau_c schedule: epoch 1 at 1 m^2, epoch 2 half-way to tau
    assert steps_a[0]["tau_c_sq_m2"] == 1.0 and steps_a[-1]["tau_c_sq_m2"] == pytest.approx(0.502)


def test_training_writes_usable_weights_and_logs(tmp_path, tiny_dataset):
    out = tmp_path / "run"
    final = train_sampler(_tiny_config(epochs=1), tiny_dataset, out, net_cfg=TINY)
    assert final["epochs_done"] == 1
    sampler = load_learned_sampler(out)  # the best weights under the versioned name
    assert sampler.net.config.width == TINY.width
    assert sampler.net.config.depth_mean_m != TINY.depth_mean_m  # normalised by the training frames
    vals = _records(out / "log.jsonl", "val")
    assert vals[0]["initial"] and len(vals) == 2
    assert "auc20cm_pct" in vals[-1] and vals[-1]["key"] == "auc20cm_pct"
    cfg = json.loads((out / "config.json").read_text())
    assert cfg["train_frames"] == 3 and cfg["val_frames"] == 1 and cfg["split"] == "splits.json"
    ckpt = torch.load(out / SAMPLER_FILE, weights_only=True)
    assert set(ckpt) == {"config", "state_dict", "meta"} and ckpt["meta"]["epoch"] == 1


def test_cli_trains_and_reports_errors(tmp_path, tiny_dataset):
    import typer
    from typer.testing import CliRunner

    from cuboidcli.cli.train_sampler import register

    app = typer.Typer()

    @app.callback()
    def main() -> None:
        """Stand-in for the ``train`` group."""

    register(app)
    runner = CliRunner()
    out = tmp_path / "cli"
    args = ["sampler", str(tiny_dataset), "--epochs", "1", "--instances", "1", "--hypotheses", "8"]
    args += ["--grid-step", "4", "--channels", "16", "--val-hypotheses", "16", "--output", str(out)]
    result = runner.invoke(app, args)
    assert result.exit_code == 0, result.output
    assert (out / SAMPLER_FILE).is_file() and (out / "last.pt").is_file()
    bad = runner.invoke(app, ["sampler", str(tmp_path / "missing")])
    assert bad.exit_code == 2 and "dataset folder not found" in bad.output
    bad = runner.invoke(app, ["sampler", str(tiny_dataset), "--samples-k", "1", "--output", str(out)])
    assert bad.exit_code == 2 and "samples_k" in bad.output


def test_trainers_read_the_official_nyu_files(tmp_path):
    """A folder with nyu_depth_v2_labeled.mat + splits.mat gives the paper's train/val split."""
    from cuboidcli.evaluation.raycast import render_depth
    from cuboidcli.learn.sampler_data import dataset_splits, prepare_scenes
    from tests.evaluation.test_evaluate import scene, write_labeled_mat, write_splits_v5

    cam = Camera.preset("nyu").with_size(80, 60)
    depths = np.stack([render_depth(cam, scene(i)) for i in range(4)])
    write_labeled_mat(tmp_path / "nyu_depth_v2_labeled.mat", depths, np.zeros((4, 60, 80, 3), np.uint8))
    write_splits_v5(tmp_path / "splits.mat", np.array([2, 4]), np.array([1, 3]))
    train, val, note = dataset_splits(tmp_path)
    assert [f.name for f in train] == ["nyu_0001", "nyu_0003"] and val == [] and "NYU" in note
    scenes = prepare_scenes(train, 2, 6)
    assert len(scenes) == 2 and scenes[0].prep.points.shape[0] > 100

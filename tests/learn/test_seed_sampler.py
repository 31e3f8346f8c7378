"""The first-point sampler (models/sampler_v3.pt) and its trainer (cuboidcli/learn/seed_train.py)."""

from pathlib import Path

import pytest
import torch

from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.prepare import prepare_points
from cuboidcli.learn.seed_train import SeedTrainConfig, record_loss, scene_records
from cuboidcli.nets.sampler import SamplerNet, SamplerNetConfig
from cuboidcli.sampling import SamplingContext
from cuboidcli.sampling.learned import LearnedSampler

WEIGHTS = Path(__file__).resolve().parents[2] / "models" / "sampler_v3.pt"


def _kl_to_prior(sampler, prep, state):
    ctx = SamplingContext(prep.points, prep.grid.index, prep.grid.shape, prep.grid.depth, state.float(), 0)
    p, _ = sampler.distributions(ctx)
    prior = (1.0 - state.double().clamp(0.0, 1.0)).clamp_min(1e-3)
    prior = prior / prior.sum()
    return float((p[0] * (p[0] / prior).log()).sum())


def test_trained_first_point_map_differs_from_its_prior(room_depth, nyu_camera):
    prep = prepare_points(room_depth[0], nyu_camera, 8).as_tensors()
    state = torch.zeros(prep.points.shape[0], dtype=torch.float64)
    state[: state.numel() // 3] = 0.95  # a third of the points explained
    trained = LearnedSampler.load(WEIGHTS)
    untrained = LearnedSampler(SamplerNet(trained.net.config))
    kl_trained = _kl_to_prior(trained, prep, state)
    kl_untrained = _kl_to_prior(untrained, prep, state)
    assert kl_untrained < 0.02  # a fresh net samples like the sequential weights
    assert kl_trained > 0.03 and kl_trained > 10 * kl_untrained, (kl_trained, kl_untrained)


def test_seed_records_score_seeds_and_train(room_depth, nyu_camera):
    prep = prepare_points(room_depth[0], nyu_camera, 8).as_tensors()
    cfg = SeedTrainConfig(hypotheses=128, steps=2)
    records = scene_records(prep, 0, FitConfig(), cfg, torch.Generator().manual_seed(0))
    assert 1 <= len(records) <= 2
    rec = records[0]
    assert rec.score.max() == pytest.approx(1.0)  # the best seed reaches the step's best gain
    assert (rec.score >= 0).all() and rec.seeds.unique().numel() == rec.seeds.numel()
    if len(records) == 2:  # the state advanced with the winner
        assert (records[1].state > 0.5).sum() > 100
    net = SamplerNet(SamplerNetConfig(maps=1, width=16, blocks=1, upsample=1, prior="unexplained"))
    loss = record_loss(net, prep, rec, cfg.kappa)
    assert torch.isfinite(loss) and float(loss.detach()) >= -1e-6  # a KL divergence
    loss.backward()
    assert net.map_head.weight.grad.abs().sum() > 0


def test_seed_training_writes_weights_and_resumes_exactly(tmp_path):
    """train_seed_sampler on the training loop: the weights after every epoch, last.pt, and a resumed run
    (the seed scores recorded again) ends where the uninterrupted one does."""
    import json

    from cuboidcli.camera import Camera
    from cuboidcli.learn.seed_train import train_seed_sampler
    from tests.conftest import write_room_dataset

    data = tmp_path / "data"
    write_room_dataset(data, Camera.preset("nyu").scaled(0.25))
    fit = FitConfig(grid_step=4)
    cfg = SeedTrainConfig(hypotheses=32, steps=2, epochs=2, width=8, blocks=1)
    full = train_seed_sampler(data, tmp_path / "a", cfg, fit)
    assert full == tmp_path / "a" / "sampler_v3.pt"
    sampler = LearnedSampler.load(full)
    assert sampler.net.config.maps == 1 and sampler.net.config.prior == "unexplained"
    epochs = [json.loads(line) for line in (tmp_path / "a" / "log.jsonl").read_text().splitlines()]
    assert [r["epoch"] for r in epochs if r["event"] == "epoch"] == [1, 2]

    train_seed_sampler(data, tmp_path / "b", SeedTrainConfig(**{**cfg.__dict__, "epochs": 1}), fit)
    train_seed_sampler(data, tmp_path / "b", cfg, resume=tmp_path / "b" / "last.pt")
    a = torch.load(tmp_path / "a" / "last.pt", weights_only=True)
    b = torch.load(tmp_path / "b" / "last.pt", weights_only=True)
    assert a["epoch"] == b["epoch"] == 2 and a["step"] == b["step"] > 0
    for k, v in a["state_dict"].items():
        torch.testing.assert_close(v, b["state_dict"][k], rtol=0, atol=0)

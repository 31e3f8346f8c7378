"""The sampling-weight network (cuboidcli.nets.sampler) and its Sampler (cuboidcli.sampling.learned)."""

import pytest
import torch

from cuboidcli.camera import Camera
from cuboidcli.factories import load_learned_sampler, make_sampler
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.prepare import prepare_points
from cuboidcli.nets.checkpoint import checkpoint_dict
from cuboidcli.nets.sampler import SamplerNet, SamplerNetConfig, net_from_checkpoint
from cuboidcli.sampling import SamplingContext
from cuboidcli.sampling.learned import LearnedSampler
from cuboidcli.weights import FILES
from tests.conftest import fit_named, simple_room

TINY = SamplerNetConfig(width=16, blocks=1, upsample=2)
SAMPLER_FILE = FILES["sampler"]


@pytest.fixture(scope="module")
def small_scene():
    """simple_room rendered at 160x120, fitting grid every 4th pixel (30x40)."""
    from cuboidcli.synth.render import render_boxes

    camera = Camera.preset("nyu").scaled(0.25)
    depth, _ = render_boxes(simple_room(), camera)
    depth[:10, :20] = 0.0  # a hole: invalid fitting points
    return depth, camera


def _context(depth, camera, state=None) -> SamplingContext:
    prep = prepare_points(depth, camera, 4).as_tensors()
    n = prep.points.shape[0]
    state = torch.zeros(n) if state is None else state
    return SamplingContext(prep.points, prep.grid.index, prep.grid.shape, prep.grid.depth, state, 0)


def _random_inputs(b=2, h=12, w=16, seed=0):
    g = torch.Generator().manual_seed(seed)
    depth = torch.rand(b, h, w, generator=g) * 4 + 0.5
    valid = torch.rand(b, h, w, generator=g) > 0.3
    state = torch.rand(b, h, w, generator=g) * 2 - 1
    return torch.where(valid, depth, torch.zeros_like(depth)), state, valid


@pytest.mark.parametrize("upsample", [1, 2, 4, 8])
def test_output_shapes(upsample):
    torch.manual_seed(0)
    net = SamplerNet(SamplerNetConfig(width=16, blocks=2, upsample=upsample))
    depth, state, valid = _random_inputs(h=15, w=20)  # odd sizes survive the stride-2 layers
    out = net(depth, state, valid)
    assert out.log_p.shape == out.p.shape == (2, 4, 15, 20)
    assert out.log_q.shape == out.q.shape == (2, 4)


def test_maps_sum_to_one_over_valid_points_and_zero_elsewhere():
    torch.manual_seed(0)
    net = SamplerNet(TINY)
    depth, state, valid = _random_inputs()
    out = net(depth, state, valid)
    sums = (out.p * valid[:, None]).flatten(2).sum(-1)
    torch.testing.assert_close(sums, torch.ones(2, 4))
    invalid = ~valid[:, None].expand_as(out.p)
    assert torch.all(out.p[invalid] == 0) and torch.all(torch.isinf(out.log_p[invalid]))
    torch.testing.assert_close(out.q.sum(1), torch.ones(2))
    assert torch.all(torch.isfinite(out.log_p[~invalid]))


def test_maps_depend_on_the_state():
    torch.manual_seed(0)
    net = SamplerNet(TINY)
    depth, state, valid = _random_inputs(b=1)
    a = net(depth, state, valid).p
    b = net(depth, torch.zeros_like(state), valid).p
    assert not torch.allclose(a, b)


def test_sampler_distributions_cover_the_fitting_points(small_scene):
    depth, camera = small_scene
    torch.manual_seed(0)
    sampler = LearnedSampler(SamplerNet(TINY))
    ctx = _context(depth, camera)
    p, q = sampler.distributions(ctx)
    n = ctx.points.shape[0]
    assert p.shape == (4, n) and q.shape == (4,) and p.dtype == torch.float64
    torch.testing.assert_close(p.sum(1), torch.ones(4, dtype=torch.float64))
    torch.testing.assert_close(q.sum(), torch.tensor(1.0, dtype=torch.float64))
    assert torch.all(p > 0)  # every fitting point is a valid cell and can be drawn


def test_checkpoint_round_trip_and_load(tmp_path, small_scene):
    torch.manual_seed(0)
    net = SamplerNet(TINY)
    torch.save(checkpoint_dict(net, {"note": "test"}), tmp_path / SAMPLER_FILE)
    loaded = load_learned_sampler(tmp_path)  # a --weights folder: its sampler_v2.pt
    assert loaded.name == "learned" and loaded.net.config == TINY
    ctx = _context(*small_scene)
    torch.testing.assert_close(loaded.distributions(ctx)[0], LearnedSampler(net).distributions(ctx)[0])
    # the file itself loads the same, and make_sampler("learned") goes through the same loader
    assert LearnedSampler.load(tmp_path / SAMPLER_FILE).net.config == TINY
    assert make_sampler("learned", tmp_path).name == "learned"
    ckpt = torch.load(tmp_path / SAMPLER_FILE, weights_only=True)
    assert set(ckpt) == {"config", "state_dict", "meta"} and ckpt["meta"] == {"note": "test"}
    assert not net_from_checkpoint(ckpt).training


def test_missing_weights_raise_a_clear_error(tmp_path):
    with pytest.raises(FileNotFoundError, match="sampler weights .* not found; train them"):
        LearnedSampler.load(tmp_path / "nowhere")
    with pytest.raises(ValueError, match="not a sampler checkpoint"):
        net_from_checkpoint({"state_dict": {}})
    with pytest.raises(ValueError, match="power of two"):
        SamplerNetConfig(upsample=3)


def test_learned_sampler_plugs_into_fit_depth(tmp_path, small_scene):
    depth, camera = small_scene
    torch.manual_seed(0)
    torch.save(checkpoint_dict(SamplerNet(TINY)), tmp_path / SAMPLER_FILE)
    cfg = FitConfig(sampler="learned", hypotheses=128, grid_step=4, max_cuboids=3, refine=False, seed=1)
    cuboids, info = fit_named(depth, camera, cfg, weights=tmp_path)
    assert 1 <= len(cuboids) <= 3
    assert all(g > info.theta for g in info.gains)
    again, _ = fit_named(depth, camera, cfg, weights=tmp_path)
    assert [c.center.tolist() for c in again] == [c.center.tolist() for c in cuboids]


def test_unexplained_prior_starts_as_the_sequential_sampler(small_scene):
    """With the prior, an untrained net samples (almost) like the sequential sampler: explained points get
    ~prior_floor of the weight of unexplained ones, and every map is close to the sequential weights."""
    depth, camera = small_scene
    torch.manual_seed(0)
    net = SamplerNet(SamplerNetConfig(width=16, blocks=1, upsample=2, prior="unexplained"))
    base = _context(depth, camera)
    n = base.points.shape[0]
    state = torch.zeros(n)
    state[: n // 2] = 1.0  # the first half explained, the rest not
    state[n // 2 : n // 2 + 10] = -0.5  # occluded points count as unexplained
    ctx = _context(depth, camera, state)
    p, q = LearnedSampler(net).distributions(ctx)
    seq, _ = make_sampler("sequential").distributions(ctx)
    assert p.shape == (4, n)
    assert torch.allclose(p.sum(1), torch.ones(4, dtype=torch.float64))
    # all weight within a few per cent of the sequential sampler's (small random map-head init)
    assert float((p - seq).abs().sum(1).max()) < 0.05
    ratio = p[:, : n // 2].mean(1) / p[:, n // 2 :].mean(1)
    assert bool(((ratio > 0.5e-3) & (ratio < 2e-3)).all())  # prior_floor = 1e-3
    assert q.shape == (4,)


def test_prior_free_maps_ignore_the_state():
    torch.manual_seed(0)
    net = SamplerNet(SamplerNetConfig(width=16, blocks=1, upsample=1, prior="unexplained")).eval()
    depth, state, valid = _random_inputs()
    out = net(depth, state, valid)
    free_sum = out.log_p_free.exp().flatten(2).sum(-1)
    assert torch.allclose(free_sum, torch.ones_like(free_sum), atol=1e-5)
    plain = SamplerNet(SamplerNetConfig(width=16, blocks=1, upsample=1)).eval()
    out_plain = plain(depth, state, valid)
    assert torch.equal(out_plain.log_p, out_plain.log_p_free)  # prior "none": the same maps


def test_unknown_prior_is_an_error():
    with pytest.raises(ValueError, match="prior"):
        SamplerNetConfig(prior="sequential")


def _constant_heads(net: SamplerNet, map_bias: list[float], q_bias: list[float]) -> SamplerNet:
    """The net with its map and selection heads ignoring the features: known answers for every map."""
    with torch.no_grad():
        net.map_head.weight.zero_()
        net.map_head.bias.copy_(torch.tensor(map_bias))
        net.q_head.weight.zero_()
        net.q_head.bias.copy_(torch.tensor(q_bias))
    return net.eval()


def test_constant_heads_give_uniform_maps_and_softmax_selection_weights():
    net = _constant_heads(SamplerNet(TINY), [0.0, 5.0, -3.0, 1.0], [0.0, 1.0, 2.0, 3.0])
    depth, state, valid = _random_inputs(b=1)
    out = net(depth, state, valid)
    n_valid = int(valid.sum())
    # a map's bias shifts every logit equally: each map is uniform over the valid cells, whatever the bias
    expected = torch.where(valid[:, None], 1.0 / n_valid, 0.0).expand_as(out.p)
    torch.testing.assert_close(out.p, expected)
    q = torch.exp(torch.arange(4.0)) / torch.exp(torch.arange(4.0)).sum()
    torch.testing.assert_close(out.q[0], q)
    torch.testing.assert_close(out.log_q[0], q.log())


def test_unexplained_prior_weights_points_by_one_minus_their_state():
    """prior "unexplained" with a constant map head: p(y) = max(1 - clip(s(y), 0, 1), floor) / sum, exactly
    the sequential sampler's weights; occluded points (s < 0) weigh 1."""
    cfg = SamplerNetConfig(width=16, blocks=1, upsample=1, prior="unexplained", prior_floor=0.01)
    net = _constant_heads(SamplerNet(cfg), [0.0] * 4, [0.0] * 4)
    state = torch.tensor([[[0.0, 0.25, 0.5, 1.0], [1.7, -0.5, -3.0, 0.999]]])
    valid = torch.tensor([[[True, True, True, True], [True, True, False, True]]])
    depth = torch.full((1, 2, 4), 2.0)
    out = net(depth, state, valid)
    weights = torch.tensor([[1.0, 0.75, 0.5, 0.01], [0.01, 1.0, 0.0, 0.01]])
    expected = weights / weights.sum()
    for j in range(4):
        torch.testing.assert_close(out.p[0, j], expected, atol=1e-6, rtol=1e-5)
    # the prior-free maps stay uniform over the valid cells
    torch.testing.assert_close(out.log_p_free.exp()[0, 0], valid[0] / valid.sum(), atol=1e-6, rtol=0)


def test_encoding_normalises_depth_clips_the_state_and_zeroes_invalid_cells():
    cfg = SamplerNetConfig(width=16, blocks=1, upsample=2, depth_mean_m=3.0, depth_std_m=2.0, state_clip=1.0)
    net = SamplerNet(cfg)
    depth = torch.tensor([[[1.0, 3.0], [7.0, 4.0]]])
    state = torch.tensor([[[-5.0, 0.5], [2.0, 0.3]]])
    valid = torch.tensor([[[True, True], [True, False]]])
    x = net.encode(depth, state, valid)
    assert x.shape == (1, 2, 4, 4)
    torch.testing.assert_close(x[0, 0, ::2, ::2], torch.tensor([[-1.0, 0.0], [2.0, 0.0]]))
    torch.testing.assert_close(x[0, 1, ::2, ::2], torch.tensor([[-1.0, 0.5], [1.0, 0.0]]))
    # nearest upsampling: each grid cell becomes a 2x2 block
    torch.testing.assert_close(x[0, :, 1::2, 1::2], x[0, :, ::2, ::2])

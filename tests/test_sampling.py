import torch

from cuboidcli.fitting.sampling import (
    LocalSampler,
    SamplingContext,
    SequentialSampler,
    UniformSampler,
    draw_minimal_sets,
)


def ctx_for(hs=20, ws=30, state=None, invalid=()):
    valid = torch.ones(hs * ws, dtype=torch.bool)
    valid[list(invalid)] = False
    gi = valid.nonzero().squeeze(1)
    n = gi.numel()
    pts = torch.rand(n, 3, generator=torch.Generator().manual_seed(0)) + torch.tensor([0.0, 0.0, 2.0])
    st = torch.zeros(n) if state is None else state
    return SamplingContext(pts, gi, (hs, ws), torch.ones(hs, ws), st, 0)


def test_sequential_weights_follow_state():
    state = torch.zeros(600)
    state[:100] = 1.0  # explained points
    state[100:200] = -3.0  # occluded points keep full weight
    state[200:300] = 0.25
    p, q = SequentialSampler().distributions(ctx_for(state=state))
    assert q.tolist() == [1.0]
    w = p[0] / p[0, 500]
    assert torch.allclose(w[:100], torch.zeros(100, dtype=w.dtype))
    assert torch.allclose(w[100:200], torch.ones(100, dtype=w.dtype))
    assert torch.allclose(w[200:300], torch.full((100,), 0.75, dtype=w.dtype))
    p_u, _ = UniformSampler().distributions(ctx_for())
    assert torch.allclose(p_u.sum(1), torch.ones(1, dtype=p_u.dtype))


def test_draw_minimal_sets_respects_maps_and_selection_weights():
    g = torch.Generator().manual_seed(1)
    p = torch.zeros(2, 10, dtype=torch.float64)
    p[0, :5] = 0.2
    p[1, 5:] = 0.2
    q = torch.tensor([0.75, 0.25], dtype=torch.float64)
    idx = draw_minimal_sets(p, q, 4000, 6, g)
    assert idx.shape == (4000, 6)
    first_map = (idx < 5).all(1)
    second_map = (idx >= 5).all(1)
    assert (first_map | second_map).all()  # a set never mixes maps
    assert abs(first_map.float().mean().item() - 0.75) < 0.03


def test_local_sampler_stays_in_the_window_and_skips_invalid_cells():
    invalid = range(0, 600, 7)
    ctx = ctx_for(invalid=invalid)
    idx = LocalSampler().draw(ctx, 500, 6, torch.Generator().manual_seed(2))
    assert idx.shape == (500, 6)
    cells = ctx.grid_index[idx]
    rows, cols = cells // 30, cells % 30
    assert ((rows - rows[:, :1]).abs() <= 12).all() and ((cols - cols[:, :1]).abs() <= 12).all()
    assert not torch.isin(cells, torch.tensor(list(invalid))).any()
    # the sets are not all the seed repeated
    assert (idx != idx[:, :1]).any(1).float().mean() > 0.9

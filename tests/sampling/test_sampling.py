import torch

from cuboidcli.sampling import (
    LocalSampler,
    SamplingContext,
    SequentialSampler,
    UniformSampler,
    draw_hypotheses,
    draw_minimal_sets,
)
from cuboidcli.sampling.proposals import ball_minimal_sets, focal_in_cells


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


def _ball_ctx():
    """Two planes far apart in depth that interleave in the image: left half at 2 m, right half at 4 m,
    with every 7th cell invalid."""
    hs, ws = 20, 30
    valid = torch.ones(hs * ws, dtype=torch.bool)
    invalid = torch.arange(0, hs * ws, 7)
    valid[invalid] = False
    gi = valid.nonzero().squeeze(1)
    rows, cols = (gi // ws).double(), (gi % ws).double()
    z = torch.where(cols < 15, 2.0, 4.0).double()
    f = 50.0  # focal length in grid cells
    pts = torch.stack([(cols - 15) * z / f, (rows - 10) * z / f, z], 1).float()
    return SamplingContext(pts, gi, (hs, ws), torch.ones(hs, ws), torch.zeros(gi.numel()), 0), invalid, f


def test_ball_sets_stay_in_the_3d_ball_and_skip_invalid_cells():
    ctx, invalid, f = _ball_ctx()
    seeds = torch.arange(0, ctx.points.shape[0], 3)
    radii = (0.1, 0.3)
    idx = ball_minimal_sets(
        ctx.points,
        ctx.grid_index,
        ctx.grid_shape,
        seeds,
        6,
        torch.Generator().manual_seed(2),
        radii,
        focal_cells=(f, f),
    )
    assert idx.shape == (seeds.numel(), 6)
    assert torch.equal(idx[:, 0], seeds)
    dist = (ctx.points[idx] - ctx.points[idx[:, :1]]).norm(dim=-1)
    assert (dist <= max(radii) + 1e-6).all()
    # a ball never reaches across the 2 m depth jump, although the image window does
    z = ctx.points[idx][..., 2]
    assert torch.equal(z, z[:, :1].expand_as(z))
    assert not torch.isin(ctx.grid_index[idx], invalid).any()
    assert (idx != idx[:, :1]).any(1).float().mean() > 0.9  # the sets are not the seed repeated
    # the focal length recovered from the points matches the grid's
    fc, fr = focal_in_cells(ctx.points, ctx.grid_index, ctx.grid_shape)
    assert abs(fc - f) < 1e-3 and abs(fr - f) < 1e-3


def test_ball_sets_follow_the_weights_and_are_deterministic():
    ctx, _, f = _ball_ctx()
    n = ctx.points.shape[0]
    weights = torch.ones(n, dtype=torch.float64)
    weights[::2] = 0.0  # explained points are never drawn as members
    seeds = torch.full((400,), 40)
    draw = lambda: ball_minimal_sets(  # noqa: E731
        ctx.points,
        ctx.grid_index,
        ctx.grid_shape,
        seeds,
        6,
        torch.Generator().manual_seed(5),
        (0.5,),
        weights,
        (f, f),
    )
    idx = draw()
    assert torch.equal(idx, draw())
    assert (idx[:, 1:] % 2 == 1).all()


def test_draw_hypotheses_mixes_local_and_global_sets():
    ctx, _, _ = _ball_ctx()
    maps, idx, local = draw_hypotheses(
        SequentialSampler(), ctx, 200, 6, torch.Generator().manual_seed(0), 0.75, (0.2,)
    )
    assert idx.shape == (200, 6) and maps.shape == (200,)
    assert int(local.sum()) == 150 and bool(local[:150].all())
    spread = (ctx.points[idx] - ctx.points[idx[:, :1]]).norm(dim=-1).amax(1)
    assert (spread[:150] <= 0.2 + 1e-6).all()
    assert spread[150:].median() > 1.0  # global sets span the frame
    # the local sampler localises every set whatever the fraction asked for
    _, _, local = draw_hypotheses(LocalSampler(), ctx, 50, 6, torch.Generator().manual_seed(0), 0.0)
    assert bool(local.all())

"""Scoring on image cells (each hypothesis visits only the rows and columns it can reach) must give the
gains of the plain loop bit for bit, and exact selection must pick the same winner."""

import numpy as np
import pytest
import torch

from cuboidcli.camera import Camera
from cuboidcli.fitting.backend import NumbaBackend
from cuboidcli.fitting.prepare import prepare_points
from cuboidcli.fitting.scoring import ScoreParams
from cuboidcli.geometry import kernels as K
from cuboidcli.geometry.cells import ImageCells
from cuboidcli.geometry.fused import score_gains
from cuboidcli.geometry.rotations import axis_angle_to_matrix

TAU, BETA = 0.004, 5.0


def grid_scene(h=400, seed=0):
    """A room-like depth map with holes on a 640x480 camera (step 8), hypotheses of every size around its
    points, some reaching behind the camera, and a state with occluded, explained and open points."""
    cam = Camera.preset("nyu")
    rng = np.random.default_rng(seed)
    v, u = np.mgrid[0:480, 0:640].astype(float)
    depth = 3.0 + 0.8 * np.sin(u / 90.0) + 0.5 * (v / 480.0)
    depth[100:220, 200:330] = 1.6  # a box in front
    depth[rng.random(depth.shape) < 0.2] = 0.0  # holes
    prep = prepare_points(depth, cam, 8).as_tensors()
    pts = prep.points.double()
    g = torch.Generator().manual_seed(seed)
    n = pts.shape[0]
    c = pts[torch.randint(0, n, (h,), generator=g)] + torch.randn(h, 3, generator=g).double() * 0.1
    c[:10, 2] = torch.linspace(-0.5, 0.5, 10).double()  # boxes around the camera: the whole grid
    a = torch.rand(h, 3, generator=g).double() ** 2 * 1.5 + 0.01
    R = axis_angle_to_matrix(torch.randn(h, 3, generator=g).double())
    state = K.oai_of_set(pts, c[10:13], a[10:13], R[10:13], TAU, BETA, 2 * TAU)
    return prep, pts, c, a, R, state


@pytest.mark.parametrize("oai", [True, False])
def test_cells_give_the_same_gains_bit_for_bit(oai):
    prep, pts, c, a, R, state = grid_scene()
    assert (state < 0).sum() > 20 and (state > 0.5).sum() > 20
    args = (pts.numpy(), c.numpy(), a.numpy(), R.numpy(), state.numpy(), TAU, BETA, 2 * TAU, oai)
    plain = score_gains(*args)
    culled = score_gains(*args, cells=prep.grid.cells)
    assert np.array_equal(plain, culled)
    assert (plain != 0).sum() > 100


def test_cells_pruning_keeps_every_hypothesis_that_reaches_the_threshold():
    prep, pts, c, a, R, state = grid_scene(seed=1)
    args = (pts.numpy(), c.numpy(), a.numpy(), R.numpy(), state.numpy(), TAU, BETA, 2 * TAU)
    full = score_gains(*args)
    thr = np.sort(full)[-6]
    pruned = score_gains(*args, prune_below=thr, cells=prep.grid.cells)
    kept = np.isfinite(pruned)
    assert kept.sum() >= 6 and (~kept).sum() > 300
    assert np.array_equal(pruned[kept], full[kept])
    assert (full[~kept] < thr).all()


def test_cells_must_hold_the_points():
    prep, pts, c, a, R, state = grid_scene()
    with pytest.raises(ValueError, match="cells hold"):
        score_gains(pts[:-1].numpy(), c.numpy(), a.numpy(), R.numpy(), state[:-1].numpy(), TAU, BETA, 0.008,
                    cells=prep.grid.cells)  # fmt: skip
    with pytest.raises(ValueError, match="sorted"):
        ImageCells.of_grid(np.array([3, 1]), np.zeros(4), np.zeros(1))


def test_subgrid_holds_every_other_row_and_fourth_column():
    prep, pts, *_ = grid_scene()
    cols = prep.grid.shape[1]
    idx, sub = prep.grid.cells.subgrid(2, 4)
    r, c = np.divmod(prep.grid.index.numpy()[idx], cols)
    assert (r % 2 == 0).all() and (c % 4 == 0).all()
    every = np.divmod(prep.grid.index.numpy(), cols)
    assert len(idx) == ((every[0] % 2 == 0) & (every[1] % 4 == 0)).sum()
    assert sub.shape == (30, 20) and sub.start[-1] == len(idx)
    assert np.array_equal(sub.col_u, prep.grid.cells.col_u[::4])


def test_exact_selection_on_cells_nominates_the_true_winner():
    prep, pts, c, a, R, state = grid_scene(h=1000, seed=2)
    sp = ScoreParams(TAU, BETA, 2 * TAU)
    full = score_gains(pts.numpy(), c.numpy(), a.numpy(), R.numpy(), state.numpy(), TAU, BETA, 2 * TAU)
    backend = NumbaBackend()
    backend.bind_cells(prep.points, prep.grid.cells)
    best, gain, g = backend.select_best(prep.points, c, a, R, state, sp, torch.Generator().manual_seed(0))
    assert best == full.argmax() and gain == full.max()
    assert np.isfinite(g.numpy()).sum() < 100  # the rest was pruned
    # nomination = the best 16 on the regular eighth of the grid, whatever the blocks prune
    idx, sub = prep.grid.cells.subgrid(2, 4)
    sub_gains = score_gains(pts[idx].numpy(), c.numpy(), a.numpy(), R.numpy(), state[idx].numpy(), TAU, BETA,
                            2 * TAU)  # fmt: skip
    top = backend._nominate(prep.points, c, a, R, state, sp, prep.grid.cells, 16)
    assert set(top.tolist()) == set(np.argsort(-sub_gains, kind="stable")[:16].tolist())


def test_scoring_arrays_follow_a_state_changed_in_place():
    prep, pts, c, a, R, state = grid_scene(seed=3)
    sp = ScoreParams(TAU, BETA, 2 * TAU)
    backend = NumbaBackend()
    backend.bind_cells(prep.points, prep.grid.cells)
    s = state.clone()
    before = backend.gains(prep.points, c, a, R, s, sp)
    s.fill_(0.0)
    after = backend.gains(prep.points, c, a, R, s, sp)
    ref = score_gains(pts.numpy(), c.numpy(), a.numpy(), R.numpy(), np.zeros(len(s)), TAU, BETA, 2 * TAU)
    assert np.array_equal(after, ref) and not np.array_equal(before, after)

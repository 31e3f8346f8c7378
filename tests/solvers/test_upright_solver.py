"""Upright (yaw-only) hypotheses: the numerical solver's solve_upright, the projection any other solver's
boxes get (solvers/base.py), and their share of each batch under an alignment (fitting/search.py)."""

from __future__ import annotations

import numpy as np
import pytest
import torch

from cuboidcli.fitting.align import Alignment
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.search import solve_sets
from cuboidcli.solvers.adam_fused import adam_solve
from cuboidcli.solvers.base import solve_upright, upright_nearest
from cuboidcli.solvers.numerical import NumericalSolver

UP = np.array([0.0, -0.8, -0.6])  # a camera pitched down: up has a component towards the camera


def _rz(deg: float) -> np.ndarray:
    t = np.deg2rad(deg)
    return np.array([[np.cos(t), -np.sin(t), 0.0], [np.sin(t), np.cos(t), 0.0], [0.0, 0.0, 1.0]])


def _box_sets(frame: np.ndarray, yaw_deg: float, n_sets: int = 8, seed: int = 0) -> torch.Tensor:
    """Minimal sets of six points on two side faces and the top of an upright box (half-sizes 0.5, 0.3,
    0.4 in the world frame, yaw ``yaw_deg``), in camera coordinates: (n_sets, 6, 3)."""
    rng = np.random.default_rng(seed)
    half = np.array([0.5, 0.3, 0.4])
    rot = frame @ _rz(yaw_deg)
    sets = []
    for _ in range(n_sets):
        loc = rng.uniform(-1, 1, (6, 3)) * half
        loc[:2, 0] = half[0]
        loc[2:4, 1] = -half[1]
        loc[4:, 2] = half[2]
        sets.append(loc @ rot.T + np.array([0.3, 0.8, 3.0]))
    return torch.from_numpy(np.stack(sets))


def _up_column_error(rotations: torch.Tensor, up: np.ndarray) -> np.ndarray:
    """Per rotation, 1 - |cos| of the angle between up and its most vertical column."""
    return 1.0 - np.abs(rotations.numpy().transpose(0, 2, 1) @ up).max(1)


def _axis_error_deg(frame: np.ndarray, r: torch.Tensor, yaw_deg: float) -> np.ndarray:
    """Per box, the angle between the true box's first horizontal axis and the nearest box axis."""
    world = frame.T @ r.numpy()  # (H, 3, 3) axes in the world frame
    cos = np.abs(np.einsum("i,hij->hj", _rz(yaw_deg)[:, 0], world)).max(1)
    return np.degrees(np.arccos(np.clip(cos, -1.0, 1.0)))


def test_upright_boxes_recover_a_yawed_box():
    frame = Alignment("gravity", UP).frame()
    sets = _box_sets(frame, 30.0, n_sets=64)
    c, a, r = solve_upright(NumericalSolver(), sets, torch.from_numpy(frame))
    assert np.all(_up_column_error(r, UP / np.linalg.norm(UP)) < 1e-9)  # exactly upright
    assert np.allclose(np.linalg.det(r.numpy()), 1.0)
    # six points leave a box's yaw ambiguous, but far less than its full rotation: the upright boxes' axes
    # are half as far from the truth as the free solver's (measured: median 15 vs 30 degrees)
    c_free, _, r_free = NumericalSolver()(sets)
    up_err = _axis_error_deg(frame, r, 30.0)
    assert np.median(up_err) < 0.6 * np.median(_axis_error_deg(frame, r_free, 30.0))
    assert np.percentile(up_err, 25) < 6.0
    # and its centre is no further from the truth than the free boxes' (a box through six points ends at
    # them, so neither is at the true centre)
    truth = np.array([0.3, 0.8, 3.0])
    dist = np.median(np.linalg.norm(c.numpy() - truth, axis=1))
    assert dist < 0.2 and dist <= np.median(np.linalg.norm(c_free.numpy() - truth, axis=1)) + 0.02


def test_fixed_upright_boxes_keep_the_frames_axes():
    frame = Alignment("gravity", UP).frame()
    _, _, r = solve_upright(NumericalSolver(), _box_sets(frame, 0.0), torch.from_numpy(frame), fixed=True)
    assert np.allclose(r.numpy(), frame[None], atol=1e-12)


def test_adam_rotation_degrees_of_freedom():
    sets = _box_sets(np.eye(3), 20.0, n_sets=4).numpy()
    init = np.zeros((4, 9))
    init[:, :3] = sets.mean(1)
    init[:, 3:6] = [0.05, -0.03, 0.1]
    init[:, 6:] = 0.3
    for dof, kept in ((0, slice(3, 6)), (1, slice(3, 5))):
        out = init.copy()
        adam_solve(sets, init, 1e-3, 2.0, 0.01, 20, out, dof)
        assert np.array_equal(out[:, kept], init[:, kept]), dof
    out = init.copy()
    adam_solve(sets, init, 1e-3, 2.0, 0.01, 20, out, 1)
    assert not np.allclose(out[:, 5], init[:, 5])  # the yaw moves


def test_upright_nearest_is_a_proper_upright_rotation_close_to_the_input():
    tilt = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.1), -np.sin(0.1)], [0.0, np.sin(0.1), np.cos(0.1)]])
    r = torch.from_numpy(np.stack([_rz(40.0) @ tilt, tilt @ _rz(-75.0)[[2, 0, 1]].T]))
    out = upright_nearest(r).numpy()
    assert np.allclose(np.linalg.det(out), 1.0)
    assert np.allclose(np.abs(out[:, 2, :]).max(1), 1.0)  # one column is exactly z
    assert np.all(np.abs(np.einsum("hij,hij->h", out, r.numpy())) > 2.8)  # within ~10 degrees


def test_upright_nearest_equals_the_rotation_of_each_box():
    from cuboidcli.geometry.gravity import upright_rotation
    from cuboidcli.geometry.rotations import axis_angle_to_matrix

    r = axis_angle_to_matrix(
        torch.randn(300, 3, generator=torch.Generator().manual_seed(0), dtype=torch.float64)
    )
    r[0] = torch.eye(3, dtype=torch.float64)  # already upright: unchanged
    out = upright_nearest(r).numpy()
    ref = np.stack([upright_rotation(x, np.array([0.0, 0.0, 1.0])) for x in r.numpy()])
    np.testing.assert_allclose(out, ref, atol=1e-12)


@pytest.mark.parametrize("mode,axes", [("gravity", None), ("manhattan", "room")])
def test_a_share_of_each_batch_is_upright(mode, axes):
    frame = Alignment("gravity", UP).frame()
    room = np.stack([UP / np.linalg.norm(UP), frame[:, 0], frame[:, 1]], 1) if axes else None
    al = Alignment(mode, UP / np.linalg.norm(UP), room)
    sets = _box_sets(frame, 25.0, n_sets=40)
    _, _, r = solve_sets(NumericalSolver(), sets, FitConfig(upright_fraction=0.5), al)
    err = _up_column_error(r, al.up)
    assert (err < 1e-9).sum() >= 20  # the last half at least (free boxes may be upright by chance)
    assert np.all(err[20:] < 1e-9)
    if mode == "manhattan":  # a quarter on the room's axes exactly
        assert np.allclose(r[20:30].numpy(), al.frame()[None], atol=1e-12)
    _, _, r0 = solve_sets(NumericalSolver(), sets, FitConfig(upright_fraction=0.0), al)
    assert (_up_column_error(r0, al.up) > 1e-6).sum() > 30  # free boxes are not upright


def test_boxes_on_the_room_axes_converge_in_fewer_steps(monkeypatch):
    import cuboidcli.solvers.numerical as numerical
    from cuboidcli.geometry.rotations import matrix_to_axis_angle

    # sets in the world frame itself (z up), on a box yawed 10 degrees off the room's axes, with 1 cm noise:
    # the bounding box the fixed solve starts from is not the optimum
    sets = _box_sets(np.eye(3), 10.0, n_sets=64, seed=4)
    sets = sets + 0.01 * torch.from_numpy(np.random.default_rng(5).normal(size=sets.shape))

    def objective(solver, fixed):
        c, a, r = solver.solve_upright(sets, fixed=fixed)
        return solver.objective(sets, c, matrix_to_axis_angle(r), a)

    short = objective(NumericalSolver(), True)  # FIXED_AXES_ITERS steps
    monkeypatch.setattr(numerical, "FIXED_AXES_ITERS", 200)
    long = objective(NumericalSolver(iters=200), True)
    assert float(((short - long) / long).median()) < 0.03  # 10 steps: 5.3 %, 30: 2.2 %, 50: 0.2 %
    # the fixed solve really runs fewer steps than the yaw-only one (0 steps: the initial boxes stay)
    monkeypatch.setattr(numerical, "FIXED_AXES_ITERS", 0)
    c, a, r = NumericalSolver().solve_upright(sets, fixed=True)
    c0, a0, _ = numerical.upright_init(sets.double(), NumericalSolver().bounds, True)
    assert torch.allclose(c, c0.to(c.dtype)) and torch.allclose(a, a0.to(a.dtype))
    c1, _, _ = NumericalSolver().solve_upright(sets, fixed=False)
    assert not torch.allclose(c1, c0.to(c1.dtype))


def test_upright_boxes_are_solved_from_the_first_points_of_their_sets():
    seen = []

    class Spy(NumericalSolver):
        def __call__(self, minimal_sets):
            seen.append(("free", minimal_sets.shape[1]))
            return super().__call__(minimal_sets)

        def solve_upright(self, minimal_sets, fixed=False):
            seen.append(("fixed" if fixed else "yaw", minimal_sets.shape[1]))
            return super().solve_upright(minimal_sets, fixed)

    frame = Alignment("gravity", UP).frame()
    al = Alignment(
        "manhattan", UP / np.linalg.norm(UP), np.stack([UP / np.linalg.norm(UP), frame[:, 0], frame[:, 1]], 1)
    )
    sets = _box_sets(frame, 25.0, n_sets=40)
    solve_sets(Spy(), sets, FitConfig(upright_fraction=0.5, upright_set_size=4), al)
    assert seen == [("free", 6), ("fixed", 4), ("yaw", 4)]
    seen.clear()
    solve_sets(Spy(), sets, FitConfig(upright_fraction=0.5, upright_set_size=6), al)
    assert seen == [("free", 6), ("fixed", 6), ("yaw", 6)]

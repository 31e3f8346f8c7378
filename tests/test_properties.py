"""Property-based tests (hypothesis): the depth and intrinsics readers, the rotation conversions and the
point-to-cuboid kernels, on generated inputs. Few examples each, so the file runs in seconds."""

from __future__ import annotations

import math
import os
import tempfile
from pathlib import Path

import cv2
import numpy as np
import pytest
import torch
from hypothesis import HealthCheck, assume, given, settings
from hypothesis import strategies as st
from hypothesis.extra.numpy import arrays

from cuboidcli.geometry import kernels as K
from cuboidcli.geometry.rotations import (
    axis_angle_to_matrix,
    matrix_to_axis_angle,
    matrix_to_quaternion,
    matrix_to_rotation_6d,
    quaternion_to_matrix,
    rotation_6d_to_matrix,
)
from cuboidcli.io.depth import InputError, parse_intrinsics, read_depth

#: Multiply every test's examples (e.g. 20 for a long local search); CI keeps the small default.
SCALE = int(os.environ.get("CUBOIDS_HYPOTHESIS_SCALE", "1"))


def examples(n: int) -> settings:
    """n generated examples (times SCALE), no deadline, the same examples on every run (no flaky CI)."""
    return settings(
        max_examples=n * SCALE,
        deadline=None,
        derandomize=True,
        suppress_health_check=[HealthCheck.too_slow],
    )


FAST = examples(25)

finite = st.floats(-10.0, 10.0, allow_nan=False, allow_infinity=False)
vec3 = st.tuples(finite, finite, finite)
quat = st.tuples(finite, finite, finite, finite).filter(lambda q: math.hypot(*q) > 0.1)


def _rotation(q) -> torch.Tensor:
    return quaternion_to_matrix(torch.tensor(q, dtype=torch.float64))


# ---------------------------------------------------------------- rotations


@FAST
@given(quat)
def test_quaternions_give_rotations_and_come_back(q):
    R = _rotation(q)
    torch.testing.assert_close(R @ R.T, torch.eye(3, dtype=torch.float64), atol=1e-12, rtol=0)
    assert torch.linalg.det(R).item() == pytest.approx(1.0, abs=1e-12)
    q2 = matrix_to_quaternion(R)
    assert q2[0] >= 0 and q2.norm().item() == pytest.approx(1.0)
    unit = torch.tensor(q, dtype=torch.float64) / math.hypot(*q)
    assert min((q2 - unit).abs().max(), (q2 + unit).abs().max()) < 1e-9  # q and -q are one rotation
    torch.testing.assert_close(quaternion_to_matrix(q2), R, atol=1e-12, rtol=0)


@FAST
@given(vec3, st.floats(0.0, math.pi - 1e-3))
def test_axis_angle_round_trip_and_fixed_axis(axis, angle):
    a = torch.tensor(axis, dtype=torch.float64)
    assume(a.norm() > 1e-3)
    r = a / a.norm() * angle
    R = axis_angle_to_matrix(r)
    torch.testing.assert_close(R @ r, r, atol=1e-12, rtol=0)  # the axis is fixed
    # the rotation angle is the trace's: 1 + 2 cos(angle)
    assert torch.trace(R).item() == pytest.approx(1.0 + 2.0 * math.cos(angle), abs=1e-12)
    torch.testing.assert_close(matrix_to_axis_angle(R), r, atol=1e-7, rtol=0)


@FAST
@given(quat, st.floats(0.1, 5.0), st.floats(-3.0, 3.0))
def test_6d_representation_round_trip_and_gram_schmidt(q, scale, shear):
    R = _rotation(q)
    torch.testing.assert_close(rotation_6d_to_matrix(matrix_to_rotation_6d(R)), R, atol=1e-12, rtol=0)
    # scaling the first column and mixing it into the second leave the rotation unchanged
    x = torch.cat([R[:, 0] * scale, R[:, 1] + shear * R[:, 0]])
    torch.testing.assert_close(rotation_6d_to_matrix(x), R, atol=1e-10, rtol=0)


# ---------------------------------------------------------------- kernels

box = st.tuples(
    vec3.map(lambda c: (c[0], c[1], abs(c[2]) + 1.0)),  # centre in front of the camera
    st.tuples(*[st.floats(0.05, 2.0)] * 3),  # half-sizes
    quat,
)
TAU, BETA, TAU_C = 0.004, 5.0, 0.008


def _boxes(boxes) -> tuple[torch.Tensor, torch.Tensor, torch.Tensor]:
    c = torch.tensor([b[0] for b in boxes], dtype=torch.float64)
    a = torch.tensor([b[1] for b in boxes], dtype=torch.float64)
    R = torch.stack([_rotation(b[2]) for b in boxes])
    return c, a, R


def _points(seed: int, n: int = 40) -> torch.Tensor:
    g = torch.Generator().manual_seed(seed)
    return torch.randn(n, 3, generator=g, dtype=torch.float64) * 2.0 + torch.tensor([0.0, 0.0, 4.0])


@FAST
@given(st.lists(box, min_size=1, max_size=4), st.integers(0, 2**31 - 1), st.randoms(use_true_random=False))
def test_kernels_do_not_depend_on_the_order_of_points_or_hypotheses(boxes, seed, rnd):
    c, a, R = _boxes(boxes)
    pts = _points(seed)
    perm_p = torch.tensor(rnd.sample(range(pts.shape[0]), pts.shape[0]))
    perm_h = torch.tensor(rnd.sample(range(len(boxes)), len(boxes)))
    per_pair = K.oai_per_cuboid(pts, c, a, R, TAU, BETA, TAU_C)  # (H, N)
    moved = K.oai_per_cuboid(pts[perm_p], c[perm_h], a[perm_h], R[perm_h], TAU, BETA, TAU_C)
    torch.testing.assert_close(moved, per_pair[perm_h][:, perm_p], atol=0, rtol=0)
    d_sq = K.cuboid_sq_distance(K.to_local(pts, c, R), a)
    torch.testing.assert_close(
        K.cuboid_sq_distance(K.to_local(pts[perm_p], c[perm_h], R[perm_h]), a[perm_h]),
        d_sq[perm_h][:, perm_p],
        atol=0,
        rtol=0,
    )
    # set functions: the order of the cuboids does not matter at all
    for f in (K.oai_of_set, lambda p, *b: K.oa_sq_distance(p, *b[:3])):
        ref = f(pts, c, a, R, TAU, BETA, TAU_C)
        torch.testing.assert_close(f(pts, c[perm_h], a[perm_h], R[perm_h], TAU, BETA, TAU_C), ref)
        torch.testing.assert_close(f(pts[perm_p], c, a, R, TAU, BETA, TAU_C), ref[perm_p])


@FAST
@given(
    box, st.lists(st.tuples(st.integers(0, 5), st.floats(-1, 1), st.floats(-1, 1)), min_size=1, max_size=12)
)
def test_a_cuboids_own_surface_points_have_zero_distance(b, spots):
    c, a, R = _boxes([b])
    local = []
    for side, u, v in spots:  # a point on side (+x, -x, +y, -y, +z, -z), (u, v) across it
        axis, sign = K.SIDE_AXIS[side], K.SIDE_SIGN[side]
        p = [0.0, 0.0, 0.0]
        others = [k for k in range(3) if k != axis]
        p[axis] = sign * a[0, axis].item()
        p[others[0]], p[others[1]] = u * a[0, others[0]].item(), v * a[0, others[1]].item()
        local.append(p)
    local_t = torch.tensor(local, dtype=torch.float64)
    pts = local_t @ R[0].T + c[0]
    d_sq = K.cuboid_sq_distance(K.to_local(pts, c, R), a)
    assert d_sq.abs().max().item() < 1e-12
    # on a side that faces the camera nothing hides the point: its occlusion-aware distance is zero too
    # (a point on a far side is hidden by the cuboid itself and is not expected to be)
    cam = K.camera_local(c, R)[0]
    facing = torch.tensor([cam[K.SIDE_AXIS[s]] * K.SIDE_SIGN[s] > a[0, K.SIDE_AXIS[s]] for s, _, _ in spots])
    if facing.any():
        oa = K.oa_sq_distance(pts[facing], c, a, R)
        assert oa.abs().max().item() < 1e-12
    # so each is a full inlier of its own cuboid on the side it lies on, f_I(0) = 1 - sigmoid(-beta)
    sides = K.side_sq_distances(K.to_local(pts, c, R), a)[0]
    own = sides[torch.arange(len(spots)), torch.tensor([s[0] for s in spots])]
    assert own.abs().max().item() < 1e-12
    assert K.inlier_fn(d_sq, TAU, BETA).min().item() == pytest.approx(1.0 / (1.0 + math.exp(-BETA)))


@FAST
@given(box, st.tuples(*[st.floats(-3.0, 3.0)] * 3))
def test_distance_inside_and_outside_a_cuboid(b, p):
    c, a, R = _boxes([b])
    local = torch.tensor([p], dtype=torch.float64)
    pts = local @ R[0].T + c[0]
    d_sq = K.cuboid_sq_distance(K.to_local(pts, c, R), a).item()
    excess = (local.abs() - a).clamp_min(0)
    if (excess == 0).all():  # inside: the gap to the nearest side
        expected = float((a - local.abs()).min()) ** 2
    else:  # outside: Euclidean distance to the box
        expected = float(excess.square().sum())
    assert d_sq == pytest.approx(expected, abs=1e-9)


# ---------------------------------------------------------------- readers


@examples(15)
@given(
    arrays(np.uint16, st.tuples(st.integers(1, 12), st.integers(1, 12))),
    st.sampled_from([0.001, 0.0002, 1 / 256]),
)
def test_depth_png_round_trip(depth, scale):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "d.png"
        cv2.imwrite(str(path), depth)
        got = read_depth(path, scale)
    assert got.dtype == np.float32 and got.shape == depth.shape
    np.testing.assert_array_equal(got, depth.astype(np.float32) * np.float32(scale))


@examples(15)
@given(arrays(np.float64, st.tuples(st.integers(1, 8), st.integers(1, 8)), elements=st.floats(width=32)))
def test_depth_npy_missing_values_become_zero(depth):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "d.npy"
        np.save(path, depth)
        got = read_depth(path)
    expected = depth.astype(np.float32)
    bad = ~np.isfinite(expected) | (expected <= 0)
    assert (got[bad] == 0).all()
    np.testing.assert_array_equal(got[~bad], expected[~bad])


@examples(30)
@given(st.binary(max_size=300), st.sampled_from([".png", ".npy", ".npz", ".exr"]))
def test_any_bytes_read_as_a_depth_map_or_an_input_error(data, suffix):
    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / f"depth{suffix}"
        path.write_bytes(data)
        try:
            depth = read_depth(path)
        except InputError as e:
            assert "\n" not in str(e)
        else:
            assert depth.ndim == 2 and np.isfinite(depth).all() and (depth >= 0).all()


numbers = st.floats(allow_nan=True, allow_infinity=True)


@examples(40)
@given(st.tuples(numbers, numbers, numbers, numbers))
def test_intrinsics_from_four_numbers(values):
    spec = ",".join(repr(v) for v in values)
    try:
        intr = parse_intrinsics(spec)
    except InputError:
        assert not all(math.isfinite(v) for v in values)
        return
    assert (intr.fx, intr.fy, intr.cx, intr.cy) == values and all(math.isfinite(v) for v in values)


@examples(40)
@given(st.text(max_size=40))
def test_any_intrinsics_text_parses_or_is_an_input_error(spec):
    try:
        intr = parse_intrinsics(spec)
    except InputError as e:
        assert "\n" not in str(e)
    else:
        assert all(math.isfinite(v) for v in (intr.fx, intr.fy, intr.cx, intr.cy))


@examples(25)
@given(
    st.dictionaries(
        st.sampled_from(["fx", "fy", "cx", "cy", "width", "height", "depth_scale"]),
        st.one_of(finite, st.text(max_size=3), st.none(), st.booleans()),
    )
)
def test_intrinsics_json_parses_or_is_an_input_error(entry):
    import json

    with tempfile.TemporaryDirectory() as d:
        path = Path(d) / "camera.json"
        path.write_text(json.dumps(entry))
        try:
            intr = parse_intrinsics(str(path))
        except InputError as e:
            assert "\n" not in str(e)
        else:
            assert all(isinstance(getattr(intr, k), float) for k in ("fx", "fy", "cx", "cy"))
            assert all(math.isfinite(getattr(intr, k)) for k in ("fx", "fy", "cx", "cy"))

"""Hand-computed values for the geometry kernels (paper Sec. 3.1, 3.2.4)."""

import math

import pytest
import torch

from cuboidcli.geometry import kernels as K

TAU, BETA = 0.004, 5.0


def unit_cube(z=3.0, dtype=torch.float64):
    """A 1 m cube centred at (0, 0, z), axis-aligned."""
    return (
        torch.tensor([[0.0, 0.0, z]], dtype=dtype),
        torch.full((1, 3), 0.5, dtype=dtype),
        torch.eye(3, dtype=dtype)[None],
    )


def kernels_for(point, dtype=torch.float64):
    c, a, R = unit_cube(dtype=dtype)
    p = torch.tensor([point], dtype=dtype)
    local = K.to_local(p, c, R)
    return (
        K.cuboid_sq_distance(local, a)[0, 0].item(),
        K.side_sq_distances(local, a)[0, 0].tolist(),
        K.occlusion_indicator(local, a, K.camera_local(c, R))[0, 0].tolist(),
    )


@pytest.mark.parametrize("dtype", [torch.float32, torch.float64])
def test_point_on_visible_face(dtype):
    d2, sides, chi = kernels_for([0.0, 0.0, 2.5], dtype)
    assert d2 == pytest.approx(0.0, abs=1e-7)
    # sides (+x, -x, +y, -y, +z, -z): front face -z touches, back face +z 1 m away, side faces 0.5 m
    assert sides == pytest.approx([0.25, 0.25, 0.25, 0.25, 1.0, 0.0], abs=1e-6)
    assert chi == [False] * 6


def test_point_inside_distance_to_nearest_face():
    d2, sides, chi = kernels_for([0.1, 0.0, 3.0])
    assert d2 == pytest.approx(0.4**2)
    assert sides[0] == pytest.approx(0.4**2) and sides[1] == pytest.approx(0.6**2)
    # only the front face (-z) lies between the point and the camera
    assert chi == [False, False, False, False, False, True]


def test_point_outside_near_an_edge():
    d2, sides, _ = kernels_for([0.8, 0.0, 2.3])
    assert d2 == pytest.approx(0.3**2 + 0.2**2)
    assert min(sides) == pytest.approx(d2)


def test_occluder_between_camera_and_point():
    # a point 0.5 m behind the cube: the front face (-z) and back face (+z) both cross its line of sight
    d2, sides, chi = kernels_for([0.0, 0.0, 4.0])
    assert chi == [False, False, False, False, True, True]
    assert sides[4] == pytest.approx(0.25) and sides[5] == pytest.approx(2.25)
    c, a, R = unit_cube()
    oa = K.oa_sq_distance(torch.tensor([[0.0, 0.0, 4.0]], dtype=torch.float64), c, a, R)
    assert oa.item() == pytest.approx(2.25)  # distance to the farthest occluding side: 1.5 m


def test_self_occluded_back_face_is_negative():
    # a point on the back face is hidden by the front face 1 m in front of it
    p = torch.tensor([[0.0, 0.0, 3.5]], dtype=torch.float64)
    c, a, R = unit_cube()
    f_io = K.side_inlier_occlusion(p, c, a, R, TAU, BETA, 2 * TAU)[0, 0]
    slope, fi_c = _leaky_slope()
    expected_front = K.inlier_fn(torch.tensor(1.0), TAU, BETA).item() - (
        slope * 1.0 + 1 - fi_c - slope * 2 * TAU
    )
    assert f_io[5].item() == pytest.approx(expected_front, rel=1e-9)
    assert K.oai_per_cuboid(p, c, a, R, TAU, BETA, 2 * TAU).item() == pytest.approx(expected_front, rel=1e-9)
    assert expected_front < -8.0


def test_line_of_sight_stops_at_the_camera():
    # a box behind the camera never occludes
    c = torch.tensor([[0.0, 0.0, -2.0]], dtype=torch.float64)
    a = torch.full((1, 3), 0.5, dtype=torch.float64)
    R = torch.eye(3, dtype=torch.float64)[None]
    p = torch.tensor([[0.0, 0.0, 2.0]], dtype=torch.float64)
    assert not K.occlusion_indicator(K.to_local(p, c, R), a, K.camera_local(c, R)).any()


def _leaky_slope():
    fi_c = 1 / (1 + math.exp(-BETA * (1 - 2.0)))
    return BETA / TAU * fi_c * (1 - fi_c), fi_c


def test_inlier_and_occlusion_functions():
    d = torch.tensor([0.0, TAU, 2 * TAU, 1.0], dtype=torch.float64)
    fi = K.inlier_fn(d, TAU, BETA)
    assert fi[0].item() == pytest.approx(1 / (1 + math.exp(-5)))
    assert fi[1].item() == pytest.approx(0.5)
    fo = K.occlusion_fn(d, TAU, BETA, 2 * TAU)
    slope, fi_c = _leaky_slope()
    assert slope == pytest.approx(8.31, abs=0.01)  # NOTES: about 8.31 per m^2
    assert fo[2].item() == pytest.approx(1 - fi_c)
    assert fo[3].item() == pytest.approx(1 - fi_c + slope * (1.0 - 2 * TAU))
    # continuous with matching slope at tau_c
    eps = 1e-7
    below = K.occlusion_fn(torch.tensor(2 * TAU - eps, dtype=torch.float64), TAU, BETA, 2 * TAU)
    above = K.occlusion_fn(torch.tensor(2 * TAU + eps, dtype=torch.float64), TAU, BETA, 2 * TAU)
    assert (above - below).item() / (2 * eps) == pytest.approx(slope, rel=1e-4)


def test_combine_and_set_value():
    new = torch.tensor([0.9, -0.5, 0.2, -1.0])
    old = torch.tensor([0.3, 0.8, -0.4, -0.2])
    assert K.combine(new, old).tolist() == pytest.approx([0.9, -0.5, -0.4, -1.0])
    # f_OAI of a set equals combining its members one by one
    g = torch.Generator().manual_seed(1)
    pts = torch.rand(300, 3, generator=g, dtype=torch.float64) * torch.tensor([4.0, 3.0, 4.0]) + torch.tensor(
        [-2.0, -1.5, 1.0]
    )
    c = pts[:3] + 0.1
    a = torch.rand(3, 3, generator=g, dtype=torch.float64) * 0.8 + 0.05
    R = torch.linalg.qr(torch.randn(3, 3, 3, generator=g, dtype=torch.float64))[0]
    R = R * torch.linalg.det(R)[:, None, None]
    joint = K.oai_of_set(pts, c, a, R, TAU, BETA, 2 * TAU)
    each = K.oai_per_cuboid(pts, c, a, R, TAU, BETA, 2 * TAU)
    seq = torch.zeros(300, dtype=torch.float64)
    for v in each:
        seq = K.combine(v, seq) if seq.abs().sum() else v
    assert torch.allclose(joint, seq)
    assert (joint < 0).any() and (joint > 0.5).any()


def test_gradcheck_float64():
    g = torch.Generator().manual_seed(2)
    pts = torch.randn(7, 3, generator=g, dtype=torch.float64) * 0.6 + torch.tensor([0.0, 0.0, 3.0])
    c = torch.tensor([[0.1, 0.0, 3.1]], dtype=torch.float64, requires_grad=True)
    a = torch.tensor([[0.4, 0.3, 0.5]], dtype=torch.float64, requires_grad=True)
    R = torch.eye(3, dtype=torch.float64)[None]
    P = pts.clone().requires_grad_(True)
    assert torch.autograd.gradcheck(lambda p, c, a: K.cuboid_sq_distance(K.to_local(p, c, R), a), (P, c, a))
    assert torch.autograd.gradcheck(lambda p, c, a: K.side_sq_distances(K.to_local(p, c, R), a), (P, c, a))
    assert torch.autograd.gradcheck(
        lambda p, c, a: K.oai_per_cuboid(p, c, a, R, TAU, BETA, 2 * TAU), (P, c, a)
    )
    d = torch.tensor([0.001, 0.01, 0.5], dtype=torch.float64, requires_grad=True)
    assert torch.autograd.gradcheck(lambda d: K.occlusion_fn(d, TAU, BETA, 2 * TAU), (d,))


def test_set_functions_of_an_empty_and_a_two_cuboid_set():
    """The empty set: state 0 and infinite OA distance for every point; with two cuboids a point on one of
    them (on its camera-facing side, hidden by neither) has OA distance 0, however far the other is."""
    pts = torch.tensor(
        [[0.0, 0.0, 2.0], [1.0, 0.2, 3.0], [-0.5, 0.1, 2.5], [0.0, 0.0, 6.0]], dtype=torch.float64
    )
    f64 = torch.float64
    none = torch.zeros(0, 3, dtype=f64)
    assert torch.equal(
        K.oai_of_set(pts, none, none, torch.zeros(0, 3, 3, dtype=f64), 0.004, 5.0, 0.008),
        torch.zeros(4, dtype=f64),
    )
    assert torch.equal(
        K.oa_sq_distance(pts, none, none, torch.zeros(0, 3, 3, dtype=f64)),
        torch.full((4,), math.inf, dtype=f64),
    )
    near = ([0.0, 0.0, 2.5], [0.5, 0.5, 0.5])  # front face z = 2 holds pts[0]
    far = ([3.0, 0.0, 8.0], [0.5, 0.5, 0.5])
    c = torch.tensor([near[0], far[0]], dtype=torch.float64)
    a = torch.tensor([near[1], far[1]], dtype=torch.float64)
    R = torch.eye(3, dtype=torch.float64).expand(2, 3, 3)
    oa = K.oa_sq_distance(pts[:1], c, a, R)
    assert oa.item() == 0.0
    # a single cuboid's set value is its own value
    one = K.oai_of_set(pts, c[:1], a[:1], R[:1], 0.004, 5.0, 0.008)
    torch.testing.assert_close(one, K.oai_per_cuboid(pts, c[:1], a[:1], R[:1], 0.004, 5.0, 0.008)[0])

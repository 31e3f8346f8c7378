"""The Kinect-like depth sensor model (cuboidcli.synth.sensor): each effect where its documentation puts it,
with its own random stream, and the same holes and noise for the same seed."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.synth.sensor import SensorOptions, depth_edges, projector_shadow, simulate_depth

CAM = Camera(300.0, 300.0, 159.5, 119.5, 320, 240)
ONLY = {  # each effect alone (the range limits always apply)
    "noise": SensorOptions(quantize_m=0.0, grazing=False, boundary=False, dropout=False),
    "grazing": SensorOptions(noise=False, quantize_m=0.0, boundary=False, dropout=False),
    "boundary": SensorOptions(noise=False, quantize_m=0.0, grazing=False, dropout=False),
    "dropout": SensorOptions(noise=False, quantize_m=0.0, grazing=False, boundary=False),
}


def _facing(shape=(240, 320)) -> np.ndarray:
    n = np.zeros((*shape, 3), np.float32)
    n[..., 2] = -1.0
    return n


def _tilted(cos: float) -> np.ndarray:
    """Unit normals (240, 320, 3) at exactly |cos| = ``cos`` to every pixel's ray of CAM."""
    u, v = np.meshgrid((np.arange(320) - CAM.cx) / CAM.fx, (np.arange(240) - CAM.cy) / CAM.fy)
    rays = np.stack([u, v, np.ones_like(u)], -1)
    rays /= np.linalg.norm(rays, axis=-1, keepdims=True)
    side = np.cross(rays, [0.0, 1.0, 0.0])
    side /= np.linalg.norm(side, axis=-1, keepdims=True)
    return (-cos * rays + np.sqrt(1 - cos**2) * side).astype(np.float32)


def _step_scene() -> np.ndarray:
    """A 1 m deep box in front of a wall 3 m away: columns 100-199 at 1 m, the rest at 3 m."""
    depth = np.full((240, 320), 3.0, np.float32)
    depth[:, 100:200] = 1.0
    return depth


def test_the_same_seed_gives_the_same_holes_and_noise():
    depth, normal = _step_scene(), _facing()
    a = simulate_depth(depth, normal, CAM, SensorOptions(), np.random.default_rng(7))
    b = simulate_depth(depth, normal, CAM, SensorOptions(), np.random.default_rng(7))
    c = simulate_depth(depth, normal, CAM, SensorOptions(), np.random.default_rng(8))
    assert a.dtype == np.float32 and a.shape == depth.shape
    assert np.array_equal(a, b)
    assert not np.array_equal(a > 0, c > 0) and not np.array_equal(a, c)


def test_each_effect_draws_from_its_own_stream():
    """Switching one effect off leaves the random pattern of the others unchanged."""
    depth, normal = _step_scene(), _facing()
    normal[:, :50] = _tilted(0.15)[:, :50]  # a surface seen at a grazing angle on the left
    full = simulate_depth(depth, normal, CAM, SensorOptions(quantize_m=0.0), np.random.default_rng(3))
    no_noise = simulate_depth(
        depth, normal, CAM, SensorOptions(noise=False, quantize_m=0.0), np.random.default_rng(3)
    )
    assert np.array_equal(full > 0, no_noise > 0)  # the same holes
    for effect in ("grazing", "boundary", "dropout"):
        off = SensorOptions(quantize_m=0.0, **{effect: False})
        without = simulate_depth(depth, normal, CAM, off, np.random.default_rng(3))
        kept = (full > 0) & (without > 0)
        assert np.array_equal(full[kept], without[kept]), effect  # the same noise on the pixels both keep
        assert ((full > 0) <= (without > 0)).all(), effect  # switching an effect off only removes holes
        assert (without > 0).sum() > (full > 0).sum(), effect


def test_range_limits():
    depth = np.full((240, 320), 2.0, np.float32)
    depth[:, :40] = 0.49  # too close
    depth[:, 40:80] = 0.5
    depth[:, 80:120] = 10.0
    depth[:, 120:160] = 10.01  # too far
    depth[:, 160:200] = 0.0  # nothing there
    options = replace(SensorOptions.clean(), min_range_m=0.5)  # (0.5 and 10 are exact in float32)
    out = simulate_depth(depth, _facing(), CAM, options, np.random.default_rng(0))
    assert (out[:, :40] == 0).all() and (out[:, 40:80] == 0.5).all()
    assert (out[:, 80:120] == 10.0).all() and (out[:, 120:200] == 0).all() and (out[:, 200:] == 2.0).all()
    # the default range is 0.4-10 m
    out = simulate_depth(depth, _facing(), CAM, SensorOptions.clean(), np.random.default_rng(0))
    assert (out[:, :80] > 0).all() and (out[:, 120:160] == 0).all()
    near = np.full((240, 320), 0.39, np.float32)
    assert (simulate_depth(near, _facing(), CAM, SensorOptions.clean(), np.random.default_rng(0)) == 0).all()


def test_noise_grows_with_the_square_of_depth_and_is_quantised():
    depth = np.full((240, 320), 1.0, np.float32)
    depth[:, 160:] = 3.0
    noisy = simulate_depth(depth, _facing(), CAM, ONLY["noise"], np.random.default_rng(1))
    err_near, err_far = noisy[:, :160] - 1.0, noisy[:, 160:] - 3.0
    assert err_near.std() == pytest.approx(0.0015, rel=0.05)  # 1.5 mm at 1 m
    assert err_far.std() == pytest.approx(0.0015 * 9.0, rel=0.05)  # z^2: 13.5 mm at 3 m
    assert abs(err_near.mean()) < 1e-4 and abs(err_far.mean()) < 1e-3
    coarse = SensorOptions(grazing=False, boundary=False, dropout=False, quantize_m=0.005)
    steps = simulate_depth(depth, _facing(), CAM, coarse, np.random.default_rng(1)) / 0.005
    assert np.allclose(steps, np.round(steps), atol=1e-3)


def test_grazing_returns_drop_linearly_between_the_two_cosines():
    depth = np.full((240, 320), 2.0, np.float32)
    lo, hi = SensorOptions().grazing_cos
    kept = {}
    for cos in (lo - 0.01, (lo + hi) / 2, lo + 0.75 * (hi - lo), hi + 0.01):
        out = simulate_depth(depth, _tilted(cos), CAM, ONLY["grazing"], np.random.default_rng(2))
        kept[cos] = float((out > 0).mean())
    values = list(kept.values())
    assert values[0] == 0.0 and values[3] == 1.0  # always dropped below, never above
    assert values[1] == pytest.approx(0.5, abs=0.02) and values[2] == pytest.approx(0.75, abs=0.02)


def test_boundary_holes_are_the_projector_shadow_and_flicker_at_depth_jumps():
    depth = _step_scene()
    out = simulate_depth(depth, _facing(), CAM, ONLY["boundary"], np.random.default_rng(4))
    holes = out == 0
    shadow = projector_shadow(depth, CAM.fx, 0.075)
    edges = depth_edges(depth)
    # the shadow: the background pixels less than fx * b * (1/1 - 1/3) = 15 px left of the box (the
    # projector sits to the right)
    assert shadow[:, 86:100].all() and not shadow[:, :86].any() and not shadow[:, 100:].any()
    assert holes[shadow].all()
    # the jumps: columns 99-100 and 199-200; about half of those pixels flicker out (edge_drop_prob)
    assert np.flatnonzero(edges.any(0)).tolist() == [99, 100, 199, 200]
    flicker = edges & ~shadow
    assert holes[flicker].mean() == pytest.approx(0.5, abs=0.1)
    assert not holes[~shadow & ~edges].any()  # nowhere else


def test_depth_edges_threshold_is_relative_beyond_five_centimetres():
    for z, jump, edge in [(1.0, 0.04, False), (1.0, 0.06, True), (3.0, 0.08, False), (3.0, 0.1, True)]:
        depth = np.full((4, 8), z, np.float32)
        depth[:, 4:] = z + jump
        found = depth_edges(depth)
        assert found[:, 3:5].all() == edge and not found[:, :3].any() and not found[:, 5:].any(), (z, jump)
    holes = np.full((4, 8), 2.0, np.float32)
    holes[:, 4:] = 0.0  # a hole is no surface: only the valid side is an edge
    assert np.flatnonzero(depth_edges(holes).any(0)).tolist() == [3]


def test_dropout_speckle_rate_and_blob_size():
    depth = np.full((480, 640), 2.0, np.float32)
    cam = Camera(500.0, 500.0, 319.5, 239.5, 640, 480)
    facing = _facing((480, 640))
    speckle = SensorOptions(noise=False, quantize_m=0.0, grazing=False, boundary=False, blobs_per_frame=0.0)
    out = simulate_depth(depth, facing, cam, speckle, np.random.default_rng(5))
    assert (out == 0).mean() == pytest.approx(0.002, rel=0.15)
    # blobs alone: filled ellipses whose semi-axes scale with the image width (here both 8 px at 640 px)
    import cv2

    for width, radius in ((640, 8), (320, 4)):
        cam_w = cam.scaled(width / 640)
        blobs = SensorOptions(
            noise=False,
            quantize_m=0.0,
            grazing=False,
            boundary=False,
            speckle_rate=0.0,
            blobs_per_frame=2.0,
            blob_radius_px=(8.0, 8.0),
        )
        sizes = []
        for seed in range(10):
            shape = (cam_w.height, cam_w.width)
            holes = (
                simulate_depth(
                    np.full(shape, 2.0, np.float32), _facing(shape), cam_w, blobs, np.random.default_rng(seed)
                )
                == 0
            )
            n, labels, stats, _ = cv2.connectedComponentsWithStats(holes.astype(np.uint8))
            for k in range(1, n):
                x, y, w, h = stats[k, :4]
                if x > 0 and y > 0 and x + w < shape[1] and y + h < shape[0]:
                    sizes.append((w, h))
        assert sizes and all(s == (2 * radius + 1, 2 * radius + 1) for s in sizes if max(s) <= 2 * radius + 1)
        assert np.median([max(s) for s in sizes]) == 2 * radius + 1


def test_inpainting_fills_every_hole_and_keeps_the_rest():
    depth, normal = _step_scene(), _facing()
    raw = simulate_depth(depth, normal, CAM, SensorOptions(), np.random.default_rng(6))
    dense = simulate_depth(depth, normal, CAM, SensorOptions(inpaint=True), np.random.default_rng(6))
    assert (raw == 0).mean() > 0.01 and (dense > 0).all()
    assert np.array_equal(dense[raw > 0], raw[raw > 0])

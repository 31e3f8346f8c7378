"""Metric scale of relative depth from the camera's height above the floor (cuboidcli.depth.scale) on a
synthetic room rendered at a known camera height, the scale removed."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.depth.scale import DepthScaling, scale_from_camera_height

CAMERA = Camera(fx=300.0, fy=300.0, cx=159.5, cy=119.5, width=320, height=240)


def render_room(camera: Camera, height: float, pitch_deg: float = 15.0, roll_deg: float = 3.0,
                table: bool = True) -> np.ndarray:  # fmt: skip
    """Depth (H, W) of a 4 x 5 x 2.7 m room (and a 1.2 x 0.8 m table top 0.75 m high) seen from a camera
    ``height`` metres above the floor, pitched down and rolled a little."""
    u, v = camera.pixel_grid()
    d = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones_like(u)], -1)
    p, r = -math.radians(pitch_deg), math.radians(roll_deg)  # pitched down: the optical axis tilts to +y
    rx = np.array([[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]])
    rz = np.array([[math.cos(r), -math.sin(r), 0], [math.sin(r), math.cos(r), 0], [0, 0, 1]])
    w = d @ (rx @ rz).T  # ray directions in the level frame (y down, camera at the origin)
    t = np.full(u.shape, np.inf)
    planes = [(1, height), (1, height - 2.7), (2, 4.0), (0, 2.0), (0, -2.0), (2, -1.0)]
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, offset in planes:
            tt = offset / w[..., axis]
            t = np.where((tt > 0) & (tt < t), tt, t)
        if table:
            tt = (height - 0.75) / w[..., 1]
            x, z = tt * w[..., 0], tt * w[..., 2]
            hit = (tt > 0) & (tt < t) & (np.abs(x - 0.3) < 0.6) & (np.abs(z - 2.6) < 0.4)
            t = np.where(hit, tt, t)
    return t.astype(np.float32)  # the ray has z = 1, so t is the depth


@pytest.mark.parametrize("height", [1.0, 1.45, 1.8])
def test_scale_recovered_within_two_percent(height):
    depth = render_room(CAMERA, height)
    noisy = depth * (1 + 0.003 * np.random.default_rng(0).standard_normal(depth.shape))
    fs = scale_from_camera_height(0.37 * noisy, CAMERA, height)
    assert fs.scale * 0.37 == pytest.approx(1.0, rel=0.02)
    assert fs.floor_distance == pytest.approx(0.37 * height, rel=0.02)
    assert np.dot(fs.down, [0.0, 1.0, 0.0]) > 0.9


@pytest.mark.parametrize("kind", ["relative", "relative-inverse"])
def test_depth_scaling_with_camera_height(kind):
    depth = render_room(CAMERA, 1.3, pitch_deg=20.0, roll_deg=-4.0)
    raw = 2.5 * depth if kind == "relative" else 1.0 / (0.8 * depth)
    scaling = DepthScaling(kind, camera_height_m=1.3)
    out = scaling.to_metres(raw, CAMERA)
    assert out.dtype == np.float32 and out.shape == depth.shape
    np.testing.assert_allclose(np.median(out / depth), 1.0, rtol=0.02)
    assert "1.3 m above the floor" in scaling.describe() and "scale" in scaling.describe()


def test_no_floor_is_one_line():
    # looking straight at a wall: no horizontal surface, no Manhattan frame
    flat = np.full((240, 320), 3.0, np.float32)
    with pytest.raises(ValueError, match="no floor found") as info:
        scale_from_camera_height(flat, CAMERA, 1.5)
    assert "\n" not in str(info.value)
    # a floor seen from above the ceiling's height: only a ceiling (above the camera) in view
    up = render_room(CAMERA, 1.5, pitch_deg=-35.0, table=False)
    with pytest.raises(ValueError, match="no floor found"):
        scale_from_camera_height(up, CAMERA, 1.5)
    with pytest.raises(ValueError, match="positive"):
        scale_from_camera_height(up, CAMERA, -1.0)
    with pytest.raises(ValueError, match="almost no valid pixels"):
        scale_from_camera_height(np.zeros((240, 320)), CAMERA, 1.5)


def test_camera_height_argument_checks():
    with pytest.raises(ValueError, match="needs no scale"):
        DepthScaling("metric", camera_height_m=1.5)
    with pytest.raises(ValueError, match="not both"):
        DepthScaling("relative", scale=2.0, camera_height_m=1.5)
    with pytest.raises(ValueError, match="camera height must be a positive"):
        DepthScaling("relative", camera_height_m=0.0)

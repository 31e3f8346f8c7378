"""Edges of cuboidcli.depth.scale: the exact scale and shift of the least-squares fit, what is refused
(constant outputs, too few pixels, non-positive scales and heights), how unknown depth stays unknown, and
the floor-height scaling on a room with a large low platform (a bed) or only a sliver of floor in view."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.depth.scale import DepthScaling, _grid_step, fit_scale_shift, scale_from_camera_height

CAMERA = Camera(fx=300.0, fy=300.0, cx=159.5, cy=119.5, width=320, height=240)
SMALL = Camera(fx=4.0, fy=4.0, cx=1.5, cy=0.5, width=4, height=2)


def render(height: float, pitch_deg: float, platform: tuple[float, float, float, float] | None = None):
    """Depth (240, 320) of a 4 x 5 x 2.7 m room seen from ``height`` m above the floor, pitched down by
    ``pitch_deg`` and rolled 3 degrees; ``platform``: (top's height above the floor, half width, distance
    of its centre, half depth) of a horizontal box top in front of the camera."""
    u, v = CAMERA.pixel_grid()
    d = np.stack([(u - CAMERA.cx) / CAMERA.fx, (v - CAMERA.cy) / CAMERA.fy, np.ones_like(u)], -1)
    p, r = -math.radians(pitch_deg), math.radians(3.0)
    rx = np.array([[1, 0, 0], [0, math.cos(p), -math.sin(p)], [0, math.sin(p), math.cos(p)]])
    rz = np.array([[math.cos(r), -math.sin(r), 0], [math.sin(r), math.cos(r), 0], [0, 0, 1]])
    w = d @ (rx @ rz).T  # ray directions in the level frame (y down), z = 1 in the camera frame
    t = np.full(u.shape, np.inf)
    with np.errstate(divide="ignore", invalid="ignore"):
        for axis, offset in [(1, height), (1, height - 2.7), (2, 4.0), (0, 2.0), (0, -2.0), (2, -1.0)]:
            tt = offset / w[..., axis]
            t = np.where((tt > 0) & (tt < t), tt, t)
        if platform is not None:
            top, half_w, centre, half_d = platform
            tt = (height - top) / w[..., 1]
            x, z = tt * w[..., 0], tt * w[..., 2]
            hit = (tt > 0) & (tt < t) & (np.abs(x) < half_w) & (np.abs(z - centre) < half_d)
            t = np.where(hit, tt, t)
    return t


BED = (0.45, 1.5, 2.0, 1.0)  # 3 m wide, 2 m deep, 45 cm high, its centre 2 m ahead


def test_fit_of_two_pixels_is_exact_and_ignores_unknown_reference():
    raw = np.array([[1.0, 3.0, 5.0, np.nan], [7.0, 2.0, 4.0, 6.0]])
    ref = np.array([[2.5, 6.5, 0.0, 3.0], [np.nan, -1.0, -2.0, 0.0]])  # known at (0, 0) and (0, 1) only
    scale, shift, n = fit_scale_shift(raw, ref)
    assert n == 2 and scale == pytest.approx(2.0) and shift == pytest.approx(0.5)
    inv_ref = 1.0 / (0.25 * np.array([[1.0, 3.0], [2.0, 5.0]]) + 0.5)
    scale, shift, n = fit_scale_shift(np.array([[1.0, 3.0], [2.0, 5.0]]), inv_ref, inverse=True)
    assert n == 4 and scale == pytest.approx(0.25) and shift == pytest.approx(0.5)
    with pytest.raises(ValueError, match="has 1 valid pixels"):
        fit_scale_shift(raw, np.where(np.arange(8).reshape(2, 4) == 0, 1.0, 0.0))


def test_constant_output_is_refused_within_a_relative_tolerance():
    ref = np.array([[1.0, 2.0]])
    with pytest.raises(ValueError, match="constant"):
        fit_scale_shift(np.array([[3.0, 3.0]]), ref)
    # around 0 the tolerance is absolute (1e-12), above 1 relative to the largest magnitude
    with pytest.raises(ValueError, match="constant"):
        fit_scale_shift(np.array([[0.0, 0.7e-12]]), ref)
    assert fit_scale_shift(np.array([[0.0, 1.3e-12]]), ref)[0] == pytest.approx(1.0 / 1.3e-12, rel=1e-6)
    with pytest.raises(ValueError, match="constant"):
        fit_scale_shift(np.array([[-1000.0, -1000.0 + 5e-10]]), ref)
    scale, _, _ = fit_scale_shift(np.array([[1000.0, 1000.0 + 1e-7]]), ref)
    assert scale == pytest.approx(1e7, rel=1e-3)


def test_negative_fitted_scales_are_refused():
    with pytest.raises(ValueError, match=r"negative scale \(-1\).*try 'relative-inverse'"):
        fit_scale_shift(np.array([[1.0, 2.0]]), np.array([[2.0, 1.0]]))
    with pytest.raises(ValueError, match="try 'relative'"):
        fit_scale_shift(np.array([[1.0, 2.0]]), np.array([[1.0, 2.0]]), inverse=True)


def test_given_scale_without_shift_and_unknown_depth():
    raw = np.array([[1.0, 2.0, np.nan, -1.0], [0.0, np.inf, 0.25, 3.0]])
    out = DepthScaling("relative", scale=2.0).to_metres(raw, SMALL)
    np.testing.assert_array_equal(out, [[2.0, 4.0, 0.0, 0.0], [0.0, 0.0, 0.5, 6.0]])
    assert out.dtype == np.float32
    assert DepthScaling("relative", scale=2.0).describe() == "relative, scale 2, shift 0"
    inv = DepthScaling("relative-inverse", scale=0.5, shift=0.25).to_metres(raw, SMALL)
    np.testing.assert_allclose(inv[0], [1 / 0.75, 1 / 1.25, 0.0, 0.0])  # 1 / -0.25: unknown
    metric = DepthScaling().to_metres(raw, SMALL)
    np.testing.assert_array_equal(metric, [[1.0, 2.0, 0.0, 0.0], [0.0, 0.0, 0.25, 3.0]])


def test_describe_before_and_after_the_fit_to_partial_depth():
    ref = np.array([[2.5, 6.5, 0.0, 0.0], [0.0, 0.0, 0.0, 0.0]])
    scaling = DepthScaling("relative", ref_depth=ref)
    assert scaling.describe() == "relative, aligned to the partial depth map"
    out = scaling.to_metres(np.array([[1.0, 3.0, 5.0, 0.0], [7.0, 2.0, 4.0, 6.0]]), SMALL)
    np.testing.assert_allclose(out[0, :3], [2.5, 6.5, 10.5])
    assert scaling.alignment[2] == 2
    assert (
        scaling.describe() == "relative, aligned to the partial depth map over 2 pixels: scale 2, shift 0.5"
    )


def test_argument_bounds():
    with pytest.raises(ValueError, match="scale must be a positive number"):
        DepthScaling("relative", scale=0.0)
    assert DepthScaling("relative", camera_height_m=0.5).camera_height_m == 0.5  # a table-top camera
    with pytest.raises(ValueError, match="positive"):
        scale_from_camera_height(render(1.4, 30.0), CAMERA, 0.0)


def test_grid_step_gives_about_160_cells_along_the_longer_side():
    assert _grid_step(240, 320) == 2
    assert _grid_step(100, 60) == 1
    assert _grid_step(420, 560) == 4  # 3.5 cells rounds to even


@pytest.mark.parametrize("units", [0.01, 0.37, 100.0])
def test_floor_scale_is_exact_in_any_units_and_not_fooled_by_a_bed(units):
    # the bed's top (45 cm) holds a large horizontal patch above the floor: the floor is the lowest plane
    depth = render(1.4, 30.0, BED)
    fs = scale_from_camera_height(units * depth, CAMERA, 1.4)
    assert fs.scale * units == pytest.approx(1.0, rel=1e-4)
    assert fs.floor_distance == pytest.approx(1.4 * units, rel=1e-4)
    assert 1000 < fs.floor_cells < 20000  # grid cells of the floor, not a share
    with pytest.raises(dataclasses.FrozenInstanceError):
        fs.scale = 1.0


def test_a_sliver_of_floor_is_not_a_large_plane():
    # pitched down 23 degrees the bed hides the floor but for ~300 grid cells (under 3 % of the view's
    # ~19000): the bed's top is the lowest large plane, 0.95 m below the camera
    depth = render(1.4, 23.0, BED)
    fs = scale_from_camera_height(depth, CAMERA, 1.4)
    assert fs.floor_distance == pytest.approx(0.95, rel=1e-4)


@pytest.mark.parametrize("top", [0.05, 0.06, 0.1, 0.15])
def test_a_low_dais_next_to_the_floor_is_not_averaged_into_it(top):
    # a 3 x 1.8 m dais a few cm high shows more horizontal cells (~9000) than the floor around it (~4000)
    # and lies within a few height slices of it: only the floor's own slices give its height
    fs = scale_from_camera_height(render(1.4, 30.0, (top, 1.5, 2.2, 0.9)), CAMERA, 1.4)
    assert fs.floor_distance == pytest.approx(1.4, rel=1e-4)
    assert 3000 < fs.floor_cells < 5000


def test_unknown_depth_stays_unknown_with_the_camera_height():
    depth = render(1.4, 30.0)
    raw = 0.3 * depth  # below 1 everywhere: the relative units are arbitrary
    raw[:20] = 0.0
    raw[20:30] = np.nan
    out = DepthScaling("relative", camera_height_m=1.4).to_metres(raw, CAMERA)
    assert (out[:30] == 0).all()
    np.testing.assert_allclose(out[30:], depth[30:], rtol=1e-4)
    inv = DepthScaling("relative-inverse", camera_height_m=1.4).to_metres(
        1 / np.where(raw > 0, raw, np.inf), CAMERA
    )
    np.testing.assert_allclose(inv[30:], depth[30:], rtol=1e-4)
    assert (inv[:30] == 0).all()


def test_too_few_valid_pixels():
    depth = np.zeros((240, 320))
    depth[:9, :11] = 2.0  # 99 pixels
    with pytest.raises(ValueError, match="almost no valid pixels"):
        scale_from_camera_height(depth, CAMERA, 1.4)
    depth[9, 0] = 2.0  # 100: enough to look for the floor (which a flat patch lacks)
    with pytest.raises(ValueError, match="gravity could not be estimated"):
        scale_from_camera_height(depth, CAMERA, 1.4)

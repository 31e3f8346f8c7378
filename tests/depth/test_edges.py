"""Depth-discontinuity mask (cuboidcli/depth/edges.py) on synthetic depth maps of known geometry."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from cuboidcli.depth.edges import depth_edge_mask, drop_depth_edges

F_REL = 0.81  # NYU: fx / width


def box_before_wall(width: int, smear_frac: float = 1 / 64) -> tuple[np.ndarray, np.ndarray]:
    """A fronto-parallel box face at 2 m in front of a wall at 3 m, the step smeared linearly over
    ``smear_frac`` of the width (as an upsampled network prediction is; 0 = a sharp step). Returns
    (depth, band): band = the pixels whose depth lies strictly between the two surfaces (the floating
    points)."""
    h = width * 3 // 4
    depth = np.full((h, width), 3.0, np.float32)
    depth[int(0.3 * h) : int(0.7 * h), int(0.35 * width) : int(0.65 * width)] = 2.0
    k = round(smear_frac * width)
    if k > 1:
        depth = cv2.blur(depth, (k, k), borderType=cv2.BORDER_REPLICATE)
    band = (depth > 2.05) & (depth < 2.95)
    return depth, band


def floor_view(width: int, height_m: float = 1.5, pitch_deg: float = 10.0, max_m: float = 8.0) -> np.ndarray:
    """Depth of a floor plane seen by a camera ``height_m`` above it, pitched down by ``pitch_deg``; rays
    that meet no floor within ``max_m`` (depth) are missing (0)."""
    h = width * 3 // 4
    f = F_REL * width
    v, u = np.mgrid[0:h, 0:width].astype(np.float64)
    y = (v + 0.5 - h / 2) / f  # camera y points down
    p = math.radians(pitch_deg)
    down = y * math.cos(p) + math.sin(p)  # world-down component of the ray (x, y, 1)
    with np.errstate(divide="ignore"):
        z = np.where(down > 1e-9, height_m / down, 0.0)
    z[z > max_m] = 0.0
    return z.astype(np.float32)


def interior(mask: np.ndarray, margin: int) -> np.ndarray:
    """``mask`` shrunk by ``margin`` pixels."""
    k = np.ones((2 * margin + 1, 2 * margin + 1), np.uint8)
    return cv2.erode(mask.astype(np.uint8), k).astype(bool)


def test_smeared_band_is_flagged_flat_interiors_are_not():
    depth, band = box_before_wall(640)
    mask = depth_edge_mask(depth, focal_px=F_REL * 640)
    assert band.sum() > 1000
    assert mask[band].mean() > 0.97  # the floating points go (the corners ramp more gently)
    box = np.zeros_like(band)
    box[int(0.3 * 480) : int(0.7 * 480), int(0.35 * 640) : int(0.65 * 640)] = True
    far_from_step = interior(box, 20) | interior(~box, 20)
    assert not mask[far_from_step].any()  # flat surfaces stay
    assert mask.mean() < 0.1


def test_tilted_floor_up_to_8m_is_kept():
    depth = floor_view(640)
    valid = depth > 0
    assert depth.max() > 7.9 and valid.mean() > 0.4  # the floor runs out to 8 m, at a grazing angle
    mask = depth_edge_mask(depth, focal_px=F_REL * 640)
    assert mask[valid].mean() < 0.005


def test_a_much_steeper_max_angle_flags_the_far_floor():
    """The floor test has teeth: with a 60 degree limit the far (grazing) part of the floor goes."""
    depth = floor_view(640)
    mask = depth_edge_mask(depth, focal_px=F_REL * 640, max_angle_deg=60.0)
    assert mask[depth > 5].mean() > 0.9
    assert not mask[(depth > 0) & (depth < 2.0)].any()


@pytest.mark.parametrize("scene", ["box", "sharp box", "floor"])
def test_same_regions_at_any_resolution(scene):
    """A smeared step (smear in proportion to the image, as an upsampled prediction), a sharp one (a one
    pixel step at every size: the flagged band must still be the same share of the image) and a floor."""
    fractions = []
    for width in (640, 2560):
        if scene == "floor":
            depth = floor_view(width)
        else:
            depth = box_before_wall(width, 1 / 64 if scene == "box" else 0.0)[0]
        fractions.append(depth_edge_mask(depth, focal_px=F_REL * width).mean())
    assert fractions[1] == pytest.approx(fractions[0], abs=0.002)
    if scene != "floor":
        assert fractions[0] > 0.01


def test_small_maps_scale_the_window_too():
    big = depth_edge_mask(box_before_wall(640, 0.0)[0], focal_px=F_REL * 640).mean()
    small = depth_edge_mask(box_before_wall(160, 0.0)[0], focal_px=F_REL * 160).mean()
    assert big > 0.01
    assert small == pytest.approx(big, rel=0.2)


def test_missing_depth_stays_missing_and_makes_no_edge():
    depth, band = box_before_wall(640)
    depth[50:120, 50:200] = 0.0  # a hole in the wall
    depth[int(0.5 * 480) :, 560:] = 0.0  # a hole at the border
    depth[400:410, 300:310] = np.nan
    odd = np.zeros_like(band)
    odd[1::2, 1::2] = True
    depth[band & odd] = 0.0  # single-pixel holes in the band, between the working map's samples
    out, fraction = drop_depth_edges(depth, focal_px=F_REL * 640)
    holes = ~(np.isfinite(depth) & (depth > 0))
    assert (out[holes & np.isfinite(depth)] == 0).all()
    assert np.isnan(out[400:410, 300:310]).all()  # untouched, still missing
    mask = depth_edge_mask(depth, focal_px=F_REL * 640)
    assert not mask[holes].any()
    # the wall around the holes is flat: nothing flagged there
    assert not mask[40:130, 40:210].any()
    assert not mask[int(0.5 * 480) :, 540:].any()
    assert mask[band & ~holes].mean() > 0.97
    assert fraction == pytest.approx(mask.sum() / (~holes).sum())


def test_drop_returns_a_new_map_with_edges_zeroed():
    depth, _ = box_before_wall(640)
    before = depth.copy()
    out, fraction = drop_depth_edges(depth, focal_px=F_REL * 640)
    mask = depth_edge_mask(depth, focal_px=F_REL * 640)
    assert np.array_equal(depth, before)
    assert out.dtype == depth.dtype and out.shape == depth.shape
    assert (out[mask] == 0).all() and np.array_equal(out[~mask], depth[~mask])
    assert 0.02 < fraction < 0.1


def test_all_missing_and_bad_arguments():
    out, fraction = drop_depth_edges(np.zeros((48, 64), np.float32))
    assert fraction == 0.0 and not out.any()
    with pytest.raises(ValueError):
        depth_edge_mask(np.ones((4, 4, 3), np.float32))
    with pytest.raises(ValueError):
        depth_edge_mask(np.ones((4, 4), np.float32), max_angle_deg=90.0)

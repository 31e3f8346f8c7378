"""Outputs of frames larger than the images are drawn at: bounded overlays, panels and GLB clouds that still
show the frame's own cuboids where its pixels see them; small frames drawn exactly as before."""

from __future__ import annotations

import json
import warnings

import cv2
import numpy as np
import pytest
import trimesh

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid, palette_color
from cuboidcli.export import FittedData, raycast, write
from cuboidcli.export.outputs import write_json_last
from cuboidcli.export.overlay import MAX_IMAGE_SIDE, draw_overlay, drawing_size, render_images
from cuboidcli.export.writers import MAX_CLOUD_PIXELS, cloud_step
from cuboidcli.io.result import FitResult, read_result

# A 2400x1800 frame: above MAX_IMAGE_SIDE, drawn at 1600x1200 (scale 2/3).
BIG = Camera(fx=2250.0, fy=2250.0, cx=1199.5, cy=899.5, width=2400, height=1800)
SMALL = Camera(fx=60.0, fy=60.0, cx=31.5, cy=23.5, width=64, height=48)
WALL_M = 5.0


def _boxes() -> list[Cuboid]:
    turn = cv2.Rodrigues(np.array([0.2, -0.4, 0.1]))[0]
    return [
        Cuboid([-0.45, 0.1, 2.0], [0.25, 0.3, 0.2], turn, inlier_gain=40.0),
        Cuboid([0.5, 0.2, 2.5], [0.3, 0.2, 0.3], np.eye(3), inlier_gain=25.0),
    ]


def _frame(camera: Camera) -> tuple[FittedData, np.ndarray]:
    """The boxes in front of a wall, seen by ``camera``: the fitted frame (depth and a gradient image) and
    the full-size ray cast's labels."""
    cuboids = _boxes()
    seen = raycast(camera, cuboids)
    depth = np.where(seen.label >= 0, seen.depth_m, WALL_M).astype(np.float32)
    rgb = np.zeros((camera.height, camera.width, 3), np.uint8)
    rgb[..., 0] = (np.arange(camera.width) * 255 // max(camera.width - 1, 1)).astype(np.uint8)[None, :]
    rgb[..., 1] = (np.arange(camera.height) * 255 // max(camera.height - 1, 1)).astype(np.uint8)[:, None]
    record = FitResult(camera=camera, cuboids=cuboids, settings={"tau_sq_m2": 0.004})
    return FittedData.of_record(record, depth_m=depth, rgb=rgb), seen.label


def test_drawing_size_bounds_the_longer_side_and_keeps_the_aspect():
    assert drawing_size(BIG) == (1600, 1200)
    assert drawing_size(SMALL) == (64, 48)
    assert drawing_size(Camera(1.0, 1.0, 0.0, 0.0, 3000, 4000)) == (1200, 1600)
    assert drawing_size(Camera(1.0, 1.0, 0.0, 0.0, 4032, 3024), 1600) == (1600, 1200)
    assert drawing_size(BIG, None) == (2400, 1800)


def test_images_of_a_large_frame_are_drawn_at_a_bounded_size(tmp_path):
    fitted, full_labels = _frame(BIG)
    written = write_json_last(fitted, tmp_path / "big.json", ("overlay",))
    for key in ("overlay", "labels", "labels_color"):
        image = cv2.imread(str(written[key]), cv2.IMREAD_UNCHANGED)
        assert image.shape[:2] == (1200, 1600), key
    # the panel's four tiles are at most half the bound on their longer side
    panel = cv2.imread(str(written["panel"]))
    assert panel.shape[1] == 4 * 800 + 3 * 4 and panel.shape[0] == 600 + 28
    with warnings.catch_warnings():
        warnings.simplefilter("error")  # the new entry is a known key of the schema
        saved = read_result(written["json"])
    assert saved.extras["overlay"] == {"width": 1600, "height": 1200, "scale": pytest.approx(2 / 3, abs=1e-6)}
    assert json.loads(written["json"].read_text())["camera"]["width"] == 2400  # the camera is the frame's

    # each drawn pixel shows what the frame's own pixel under its centre sees, but along silhouettes
    labels = cv2.imread(str(written["labels"]), cv2.IMREAD_UNCHANGED).astype(np.int64) - 1
    scale = 1600 / 2400
    v, u = np.mgrid[0:1200, 0:1600]
    fu = np.clip(np.round((u + 0.5) / scale - 0.5), 0, 2399).astype(int)
    fv = np.clip(np.round((v + 0.5) / scale - 0.5), 0, 1799).astype(int)
    agree = labels == full_labels[fv, fu]
    assert agree.mean() > 0.995
    assert set(np.unique(labels)) == {-1, 0, 1}


def test_the_overlay_of_a_large_frame_blends_the_boxes_over_its_shrunk_image(tmp_path):
    fitted, _ = _frame(BIG)
    images = render_images(BIG, fitted.record.cuboids, rgb=fitted.rgb, depth_m=fitted.depth_m, max_side=1600)
    overlay = images["overlay"]
    shrunk = cv2.resize(fitted.rgb, (1600, 1200), interpolation=cv2.INTER_AREA)
    # away from the boxes (their edge lines and names stay near them) the overlay is the image itself
    rows, cols = np.nonzero(images["labels"] > 0)
    away = np.ones((1200, 1600), bool)
    away[rows.min() - 10 : rows.max() + 11, cols.min() - 10 : cols.max() + 11] = False
    assert away.mean() > 0.5 and np.array_equal(overlay[away], shrunk[away])
    # on box 0 the colour leans towards the box's palette colour
    inside = cv2.erode((images["labels"] == 1).astype(np.uint8), np.ones((9, 9), np.uint8)).astype(bool)
    colour = np.array(palette_color(0), dtype=float)
    before = np.abs(shrunk[inside].astype(float) - colour).sum(axis=1)
    after = np.abs(overlay[inside].astype(float) - colour).sum(axis=1)
    assert inside.any() and (after < before).mean() > 0.99


def test_a_small_frame_is_drawn_at_its_own_size_as_before():
    fitted, full_labels = _frame(SMALL)
    bounded = render_images(
        SMALL, fitted.record.cuboids, rgb=fitted.rgb, depth_m=fitted.depth_m, max_side=1600
    )
    plain = render_images(SMALL, fitted.record.cuboids, rgb=fitted.rgb, depth_m=fitted.depth_m)
    for key in ("overlay", "labels", "labels_color", "panel"):
        assert np.array_equal(bounded[key], plain[key]), key
    assert np.array_equal(bounded["labels"].astype(int) - 1, full_labels)


def test_the_overlay_blends_covered_pixels_as_a_whole_image_blend_would():
    """Blending only the covered pixels gives the very bytes of blending the whole image in float32."""
    fitted, _ = _frame(SMALL)
    cuboids = fitted.record.cuboids
    cast = raycast(SMALL, cuboids)
    got = draw_overlay(fitted.rgb, SMALL, cuboids, cast, edge_px=0)
    alpha = 0.45
    image = fitted.rgb.astype(np.float32)
    colours = np.array([palette_color(k) for k in range(len(cuboids))], dtype=np.float32)
    covered = cast.label >= 0
    faces = colours[np.maximum(cast.label, 0)] * (0.45 + 0.55 * cast.shade)[..., None]
    whole = np.where(covered[..., None], (1.0 - alpha) * image + alpha * faces, image)
    assert np.array_equal(got, np.clip(np.round(whole), 0, 255).astype(np.uint8))


def test_the_glb_cloud_of_a_large_frame_has_a_bounded_number_of_points(tmp_path):
    fitted, _ = _frame(BIG)
    out = write(fitted, None, (), with_points=True, paths={"glb": tmp_path / "big.glb"})
    scene = trimesh.load(out["glb"], process=False)
    _, geom = scene.graph["points"]
    cloud = scene.geometry[geom]
    step = cloud_step((BIG.height, BIG.width))
    assert step == 4  # 450 x 600 pixels; a step of 3 would keep 600 x 800
    assert len(cloud.vertices) == -(-BIG.height // step) * -(-BIG.width // step) <= MAX_CLOUD_PIXELS
    # the colours are the image's at the kept pixels
    kept = fitted.rgb[::step, ::step].reshape(-1, 3)
    assert np.array_equal(np.asarray(cloud.colors)[:, :3], kept)


def test_writing_the_images_leaves_the_cuboids_as_fitted(tmp_path):
    fitted, _ = _frame(BIG)
    before = [c.to_json(i) for i, c in enumerate(fitted.record.cuboids)]
    written = write_json_last(fitted, tmp_path / "big.json", ("overlay", "glb"))
    assert json.loads(written["json"].read_text())["cuboids"] == before
    assert MAX_IMAGE_SIDE == 1600


def test_a_float_background_is_blended_from_its_own_values():
    fitted, _ = _frame(SMALL)
    cuboids = fitted.record.cuboids
    cast = raycast(SMALL, cuboids)
    background = fitted.rgb.astype(np.float64) + 0.4  # values between the bytes
    got = draw_overlay(background, SMALL, cuboids, cast, edge_px=0)
    image = background.astype(np.float32)
    colours = np.array([palette_color(k) for k in range(len(cuboids))], dtype=np.float32)
    covered = cast.label >= 0
    faces = colours[np.maximum(cast.label, 0)] * (0.45 + 0.55 * cast.shade)[..., None]
    whole = np.where(covered[..., None], (1.0 - 0.45) * image + 0.45 * faces, image)
    assert got.dtype == np.uint8
    assert np.array_equal(got, np.clip(np.round(whole), 0, 255).astype(np.uint8))

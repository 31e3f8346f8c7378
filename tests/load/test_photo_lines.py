"""A frame's photo read for its lines (load/frame.py, load/camera.py, fitting/prepare.py): the camera in
the order -K > EXIF > the lines > a depth model's focal length > the default field of view; the down
direction of a photo from its lines, a depth map's own unless unsure; the two stored forms of a photo
agree; a photo without lines falls back with one warning."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest

from cuboidcli.fitting.config import FitConfig
from cuboidcli.load import LoadOptions, load
from cuboidcli.load.camera import FOCAL_SURE
from cuboidcli.load.frame import load_frame
from tests.conftest import SHARED_DATA
from tests.geometry.test_vanishing import render_room

FX = 500.0  # the rendered room's focal length


def _angle(a, b) -> float:
    return math.degrees(math.acos(min(1.0, float(np.dot(a, b) / np.linalg.norm(a) / np.linalg.norm(b)))))


def _save_jpeg(path, upright: np.ndarray, orientation: int = 1, f35: float | None = None) -> None:
    """A JPEG as a phone writes it: orientation 6 stores the upright image turned 90 degrees
    counter-clockwise (shown turned clockwise), with the tag; ``f35`` as FocalLengthIn35mmFilm."""
    from PIL import Image

    stored = np.rot90(upright, k=1) if orientation == 6 else upright
    exif = Image.Exif()
    exif[0x0112] = orientation
    if f35 is not None:
        exif.get_ifd(0x8769)[41989] = f35
    Image.fromarray(np.ascontiguousarray(stored)).save(path, exif=exif, quality=95)


@pytest.fixture(scope="module")
def room(tmp_path_factory):
    """A rendered room photo (fx = 500 px, 640x480), its down direction, and a depth map beside it."""
    folder = tmp_path_factory.mktemp("room")
    img, down = render_room(FX, -15.0, 0.0, 30.0, seed=3)
    cv2.imwrite(str(folder / "room_rgb.png"), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    depth = np.tile(np.linspace(1500, 3500, 640), (480, 1)).astype(np.uint16)
    cv2.imwrite(str(folder / "room_depth.png"), depth)
    plain = np.dstack([np.tile(np.linspace(150, 190, 640), (480, 1))] * 3)
    plain = (plain + np.random.default_rng(0).normal(0, 2, plain.shape)).clip(0, 255).astype(np.uint8)
    cv2.imwrite(str(folder / "wall_rgb.png"), plain)  # a plain wall: no lines
    return folder, img, down


def test_the_camera_comes_from_k_then_exif_then_the_lines_then_the_default(room):
    folder, img, _ = room
    depth, rgb = folder / "room_depth.png", folder / "room_rgb.png"
    lines = load_frame(depth, rgb)  # no -K, no EXIF: the lines
    assert lines.meta["intrinsics_source"].startswith("photo lines (focal confidence ")
    assert lines.camera.fx == pytest.approx(FX, rel=0.05) and lines.camera.cx == 319.5
    assert lines.lines.focal_confidence >= FOCAL_SURE and lines.notes == []
    assert lines.meta["lines"]["focal_px"] == pytest.approx(lines.camera.fx, abs=0.01)
    _save_jpeg(folder / "exif_rgb.jpg", img, f35=26.0)  # EXIF beats the lines
    exif = load_frame(depth, folder / "exif_rgb.jpg")
    assert exif.meta["intrinsics_source"] == "exif: FocalLengthIn35mmFilm 26 mm"
    assert exif.camera.fx == pytest.approx(26 / 36 * 640)
    assert exif.lines is not None and exif.lines.focal_px is None  # found with the EXIF camera
    given = load_frame(depth, folder / "exif_rgb.jpg", intrinsics="600,600,319.5,239.5")  # -K beats all
    assert given.meta["intrinsics_source"] == "command line" and given.camera.fx == 600.0
    bare = load_frame(depth, folder / "wall_rgb.png")  # no lines: the default, with its warning
    assert bare.meta["intrinsics_source"].startswith("default: 63 degree") and bare.lines is None
    assert len(bare.notes) == 1 and "field of view" in bare.notes[0] and "lines" not in bare.meta


def test_lines_that_do_not_give_the_camera_are_seen_by_the_one_that_does(room, monkeypatch):
    """Unsure of the focal length (here: never sure, and ruling nothing out), the default field of view is
    the camera; the lines' vanishing points stay where they are in the image, their directions are the
    default camera's."""
    from cuboidcli.geometry import vanishing
    from cuboidcli.load import camera as cameras

    folder = room[0]
    img, true_down = render_room(350.0, -30.0, 0.0, 35.0, seed=350)  # wide: far from the default's 522 px
    cv2.imwrite(str(folder / "wide_rgb.png"), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    monkeypatch.setattr(cameras, "FOCAL_SURE", 1.1)
    monkeypatch.setattr(vanishing, "RULE_OUT_MARGIN", math.inf)
    frame = load_frame(folder / "room_depth.png", folder / "wide_rgb.png")
    cam = frame.camera
    assert frame.meta["intrinsics_source"].startswith("default:") and cam.fx == pytest.approx(522.2, abs=0.1)

    def k(f, c):
        return np.array([[f, 0, c.cx], [0, f, c.cy], [0, 0, 1.0]])

    seen = np.linalg.solve(k(cam.fx, cam), k(350.0, cam) @ true_down)  # the vertical vanishing point
    assert _angle(frame.lines.down, seen) < 1.0 and _angle(seen, true_down) > 5.0
    assert frame.lines.focal_px == pytest.approx(350.0, rel=0.05)  # the lines' own estimate, recorded
    assert np.allclose(frame.lines.axes[:, 0], -frame.lines.down)
    assert np.allclose(frame.lines.axes.T @ frame.lines.axes, np.eye(3), atol=1e-9)


def test_unsure_lines_that_rule_out_the_default_field_of_view_give_the_camera(room, monkeypatch):
    """Unsure of the focal length but sure it is not the default's (a wide photo: 350 px against 522),
    the lines' estimate is the camera, with one warning that says so; without lines, or with an estimate
    too spread to rule anything out, the default stays."""
    from cuboidcli.geometry import vanishing
    from cuboidcli.load import camera as cameras

    folder = room[0]
    img, _ = render_room(350.0, -30.0, 0.0, 35.0, seed=350)
    cv2.imwrite(str(folder / "wide2_rgb.png"), cv2.cvtColor(img, cv2.COLOR_RGB2BGR))
    monkeypatch.setattr(cameras, "FOCAL_SURE", 1.1)  # never sure
    frame = load_frame(folder / "room_depth.png", folder / "wide2_rgb.png")
    source = frame.meta["intrinsics_source"]
    assert source.startswith("photo lines (focal confidence ") and "rule out the default 63 degree" in source
    assert frame.camera.fx == pytest.approx(350.0, rel=0.05) and frame.camera.cx == 319.5
    assert frame.lines.rules_out(522.2) and frame.lines.focal_worse_at(522.2) >= vanishing.RULE_OUT_MARGIN
    assert len(frame.notes) == 1 and "worse" in frame.notes[0] and "-K" in frame.notes[0]
    assert frame.meta["lines"]["focal_px"] == pytest.approx(frame.camera.fx, abs=0.01)
    notes = []
    kept = cameras.default_for(640, 480, notes, None)
    assert kept.source.startswith("default: 63 degree") and len(notes) == 1
    monkeypatch.setattr(vanishing, "RULE_OUT_SD", 0.0)  # an estimate this spread rules nothing out
    notes = []
    assert cameras.default_for(640, 480, notes, frame.lines).source.startswith("default: 63 degree")


def test_the_lines_come_before_a_depth_models_focal_length(room, monkeypatch):
    from cuboidcli.load import frame

    class FocalModel:  # a depth model that predicts the focal length (as Depth Pro does)
        predicts_focal = True

        def predict_with_focal(self, rgb):
            return np.full(rgb.shape[:2], 2.0, np.float32), 777.0

        def predict(self, rgb, camera):
            return np.full(rgb.shape[:2], 2.0, np.float32)

        def describe(self):
            return "focal model"

    monkeypatch.setattr(frame, "depth_estimator", lambda opts, scale: FocalModel())
    folder = room[0]
    photo = load_frame(None, folder / "room_rgb.png")
    assert photo.meta["intrinsics_source"].startswith("photo lines") and photo.camera.fx != 777.0
    wall = load_frame(None, folder / "wall_rgb.png")
    assert wall.meta["intrinsics_source"] == "depth model: focal model" and wall.camera.fx == 777.0
    assert wall.notes == []


def test_a_photo_is_fitted_with_its_lines_down_and_a_depth_map_keeps_its_own(room):
    folder, _, true_down = room
    config = FitConfig().for_kind("frame")
    photo = load(folder / "room_rgb.png")  # depth from the built-in network, down from the lines
    g = photo.fit_input(config).gravity
    assert g.source in ("photo lines", "lines and depth") and _angle(g.down, true_down) < 2.0
    assert np.array_equal(g.down, photo.lines.down)
    # A depth map with a sure estimate of its own: the same gravity with its photo as without it.
    sample = "cuboidcli/data/sample"
    opts = LoadOptions(intrinsics=f"{sample}/camera.json")
    alone = load(f"{sample}/sample_depth.png", opts, source="depth").fit_input(config)
    seen = load(f"{sample}/sample_depth.png", opts, image=f"{sample}/sample.png", source="depth")
    checked = seen.fit_input(config)
    assert seen.lines is not None and checked.gravity.source == "lines and depth"
    assert alone.gravity.source == "depth" and checked.gravity.lines_deg < 2.0
    assert np.array_equal(alone.gravity.down, checked.gravity.down)
    assert np.array_equal(alone.alignment.axes, checked.alignment.axes)
    # A depth map without a Manhattan frame of its own (one flat wall): unsure, so its photo's lines decide.
    flat = load(folder / "room_depth.png", source="depth", image=folder / "room_rgb.png")
    assert flat.fit_input(config).gravity.source == "photo lines"
    free = load(folder / "room_depth.png", source="depth").fit_input(config)
    assert free.gravity is None and free.warnings[0].startswith("no reliable gravity in this depth map")


def test_a_photo_and_its_exif_orientation_6_copy_give_one_down_direction(room, tmp_path):
    nyu = next((SHARED_DATA / "nyu").glob("basement_00050_rgb.*"), None)
    upright = cv2.cvtColor(cv2.imread(str(nyu)), cv2.COLOR_BGR2RGB) if nyu is not None else room[1]
    _save_jpeg(tmp_path / "upright.jpg", upright, orientation=1)
    _save_jpeg(tmp_path / "turned.jpg", upright, orientation=6)
    config = FitConfig().for_kind("frame")
    a, b = load(tmp_path / "upright.jpg"), load(tmp_path / "turned.jpg")
    assert a.rgb.shape == b.rgb.shape == upright.shape
    assert a.lines is not None and b.lines is not None
    assert _angle(a.lines.down, b.lines.down) < 3.0  # measured: 0.2 degrees on the NYU photo
    ga, gb = a.fit_input(config).gravity, b.fit_input(config).gravity
    assert ga.source == gb.source == "photo lines" and _angle(ga.down, gb.down) < 3.0
    assert a.camera.fx == pytest.approx(b.camera.fx, rel=0.05)


def test_a_photo_of_a_plain_wall_falls_back_with_one_warning(room):
    import cuboidcli as cb
    from cuboidcli.io.depth import InputWarning

    fitter = cb.Fitter(hypotheses=64, max_cuboids=1, device="cpu")
    with pytest.warns(InputWarning) as caught:  # the load's notes: the default field of view
        res = fitter.fit(room[0] / "wall_rgb.png")
    notes = [str(w.message) for w in caught]
    assert len(notes) == 1 and "63 degree field of view" in notes[0]
    assert res.record.input["intrinsics_source"].startswith("default:") and "lines" not in res.record.input
    down = [w for w in res.info.warnings if "gravity" in w or "down direction" in w]
    assert len(down) == 1, res.info.warnings  # one warning about the down direction, whichever it is
    assert "lines" in down[0] and "--gravity" in down[0]
    assert len(res.cuboids) <= 1

"""The Python API (`import cuboidcli as cb`): fit a rendered room, the result's outputs, reuse of a Fitter,
the defaults shared with `cuboids fit`, and a library that never loads the command-line packages."""

from __future__ import annotations

import inspect
import json
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

import cuboidcli as cb
from cuboidcli.fitting.config import FitConfig

ROOT = Path(__file__).resolve().parents[1]
QUICK = dict(hypotheses=256, max_cuboids=5, device="cpu")


@pytest.fixture(scope="module")
def room_result(room_depth, nyu_camera):
    depth, _ = room_depth
    camera = cb.Camera(nyu_camera.fx, nyu_camera.fy, nyu_camera.cx, nyu_camera.cy)  # size from the depth
    return cb.fit(depth, camera, seed=0, **QUICK)


def test_fit_finds_the_rendered_room(room_result, room_depth):
    depth, instance = room_depth
    res = room_result
    assert isinstance(res.cuboids[0], cb.Cuboid) and 4 <= len(res.cuboids) <= 5
    assert res.camera.width == 640 and res.camera.height == 480
    # The back wall (z = 4.5 m), the left wall (x = -1.9 m), the floor (y = +1.4 m, OpenCV y down) and the
    # rotated box on the floor (centre (-0.5, 1.1, 3.0)) are found.
    centers = np.array([c.center for c in res.cuboids])
    assert np.any(np.abs(centers[:, 2] - 4.5) < 0.1) and np.any(np.abs(centers[:, 0] + 1.93) < 0.1)
    assert np.any(np.abs(centers[:, 1] - 1.4) < 0.1)
    assert np.min(np.linalg.norm(centers - [-0.5, 1.1, 3.0], axis=1)) < 0.15
    # Per-pixel labels: k for cuboid k, -1 none, -2 hidden, -3 no depth (beyond the room's open side).
    assert res.labels.shape == depth.shape and res.labels.dtype == np.int32
    assert set(np.unique(res.labels)) <= set(range(-3, len(res.cuboids)))
    assert np.array_equal(res.labels == -3, depth <= 0)
    assert (res.labels >= 0).sum() > 0.85 * (depth > 0).sum()
    # The fitting-grid labels agree with the per-pixel ones at the grid points.
    step = res.info.grid_step
    assert step == 8 and res.settings["grid_step"] is None  # chosen from the frame's size
    assert res.record.extras["fit_info"]["grid_step"] == 8
    assert res.grid_labels.shape == (480 // step, 640 // step)
    agree = (res.grid_labels == res.labels[::step, ::step]).mean()
    assert agree > 0.95
    assert res.info.stop_reason in ("max_cuboids", "gain_below_theta") and len(res.info.gains) == len(
        res.cuboids
    )


def test_result_outputs(room_result, tmp_path):
    res = room_result
    doc = res.to_json()
    assert doc["schema"] == "cuboids/1" and len(doc["cuboids"]) == len(res.cuboids)
    assert doc["settings"]["hypotheses"] == 256 and doc["input"]["depth_source"] == "array"
    assert doc["fit_info"]["gains"] == res.info.gains
    path = res.save_json(tmp_path / "r.json")
    assert json.loads(path.read_text())["cuboids"] == json.loads(json.dumps(doc["cuboids"]))
    written = res.save(tmp_path / "g.json", ("glb",), with_points=True)
    assert written == [tmp_path / "g.json", tmp_path / "g.glb"]
    assert written[1].read_bytes()[:4] == b"glTF"
    written = res.save(tmp_path / "p.json", ("ply",))
    assert written == [tmp_path / "p.json", tmp_path / "p_points.ply", tmp_path / "p_cuboids.ply"]
    assert written[1].read_bytes().startswith(b"ply")
    assert json.loads(written[0].read_text())["cuboids"] == json.loads(path.read_text())["cuboids"]
    rgb = np.full((480, 640, 3), 200, np.uint8)
    img = res.overlay(rgb)
    assert img.shape == (480, 640, 3) and img.dtype == np.uint8
    # The cuboids are drawn: a large part of the image differs from the plain background.
    assert (np.abs(img.astype(int) - 200).sum(-1) > 30).mean() > 0.3
    assert "cuboids" in repr(res)


def test_a_fitter_is_built_once_and_gives_what_fit_gives(room_depth, nyu_camera, room_result, monkeypatch):
    depth, _ = room_depth
    fitter = cb.Fitter(**QUICK)
    from cuboidcli import factories

    built = []
    monkeypatch.setattr(factories, "make_solver", lambda *a, **k: built.append(1))  # must not be called again
    first = fitter.fit(depth, nyu_camera, seed=0)
    assert [c.to_json(i) for i, c in enumerate(first.cuboids)] == [
        c.to_json(i) for i, c in enumerate(room_result.cuboids)
    ]
    # A shifted copy of the room: another frame through the same fitter, then the first one again.
    fitter.fit(np.roll(depth, 7, axis=1), nyu_camera, seed=0)
    again = fitter.fit(depth, nyu_camera, seed=0)
    assert again.to_json()["cuboids"] == first.to_json()["cuboids"] and not built
    other_seed = fitter.fit(depth, nyu_camera, seed=5)
    assert other_seed.settings["seed"] == 5 and first.settings["seed"] == 0


def test_the_settings_say_which_generator_and_backend_a_fit_ran_on(room_depth, nyu_camera, room_result):
    depth, _ = room_depth
    assert (room_result.settings["random_generator"], room_result.settings["backend_used"]) == (
        "numpy",
        "numba",
    )
    on_tensors = cb.fit(depth, nyu_camera, seed=0, **{**QUICK, "backend": "torch"})
    assert (on_tensors.settings["random_generator"], on_tensors.settings["backend_used"]) == (
        "torch",
        "torch",
    )
    assert on_tensors.settings["backend"] == "torch" and room_result.settings["backend"] == "auto"


def test_bad_input_is_a_one_line_value_error(room_depth, nyu_camera):
    depth, _ = room_depth
    with pytest.raises(ValueError, match="the depth map is 640x480 but the camera is 320x240"):
        cb.fit(depth, nyu_camera.with_size(320, 240), device="cpu")
    with pytest.raises(ValueError, match="unit looks wrong"):
        cb.fit(depth * 1000.0, nyu_camera, device="cpu")  # millimetres given as metres
    with pytest.raises(ValueError, match="2-D array"):
        cb.fit(np.zeros((4, 4, 3)), nyu_camera, device="cpu")
    with pytest.raises(ValueError, match="sampler 'best'"):
        cb.Fitter(sampler="best", device="cpu")
    with pytest.raises(TypeError, match="unknown setting 'hypothesis'"):
        cb.Fitter(hypothesis=10)


def test_reading_helpers(tmp_path, room_png):
    depth = cb.read_depth(room_png, depth_scale=0.001)
    assert depth.dtype == np.float32 and 1.0 < float(np.median(depth[depth > 0])) < 5.0
    cam = cb.read_camera("500,501,320,240")
    assert (cam.fx, cam.fy, cam.cx, cam.cy, cam.width) == (500.0, 501.0, 320.0, 240.0, 0)
    f = tmp_path / "cam.json"
    f.write_text(json.dumps({"a": {"fx": 1, "fy": 2, "cx": 3, "cy": 4, "width": 8, "height": 6}}))
    assert cb.read_camera(f, frame="a") == cb.Camera(1.0, 2.0, 3.0, 4.0, 8, 6)
    assert cb.read_camera(preset="tum").fx == 525.0
    with pytest.raises(ValueError, match="give the intrinsics"):
        cb.read_camera()


def test_library_defaults_are_the_cli_defaults():
    """`cuboids fit` without options and `cb.Fitter` / `cb.fit` without settings fit with the same
    configuration (tests/test_options.py holds each option to its FitConfig field)."""
    from cuboidcli.cli.fit import fit as fit_command
    from cuboidcli.cli.options import fit_config, option_defaults

    cli = option_defaults(fit_command)
    assert cli["device"] == "auto"
    assert inspect.signature(cb.Fitter).parameters["device"].default == "auto"
    assert inspect.signature(cb.fit).parameters["device"].default == "auto"
    assert fit_config({**cli, "device": "cpu"}) == cb.Fitter(device="cpu").config
    defaults = FitConfig()
    assert defaults.sampler == "sequential" and defaults.hypotheses == 3072


def test_cli_and_api_write_the_same_cuboids(tmp_path, room_png, room_depth, nyu_camera):
    from cuboidcli.cli.main import app

    out = tmp_path / "cli.json"
    args = ["fit", "--depth", str(room_png), "--camera", "nyu", "-o", str(out), "--hypotheses", "256"]
    r = CliRunner().invoke(app, [*args, "--max-cuboids", "5", "--device", "cpu", "-q"])
    assert r.exit_code == 0, r.output
    depth = cb.read_depth(room_png)
    res = cb.fit(depth, cb.Camera.preset("nyu"), **QUICK)
    cli_doc = json.loads(out.read_text())
    assert cli_doc["cuboids"] == json.loads(json.dumps(res.to_json()["cuboids"]))
    # the same file read the same way: the same settings, how it was read included
    read = cb.Fitter(**QUICK).fit(room_png, camera_preset="nyu")
    assert read.to_json()["cuboids"] == res.to_json()["cuboids"]
    assert {k: v for k, v in cli_doc["settings"].items() if k != "theta_used"} == {
        k: v for k, v in json.loads(json.dumps(read.settings)).items() if k != "theta_used"
    }
    assert cli_doc["settings"]["load"] == {"intrinsics": None, "camera": "nyu", "depth_scale": None}
    assert res.settings["load"] == {"intrinsics": None, "camera": None, "depth_scale": None}  # an array


def test_import_is_light_and_the_library_never_loads_the_cli_packages(tmp_path):
    depth = np.zeros((60, 80), np.float32)
    depth[:, :] = 3.0
    depth[40:, :] = 1.5
    np.save(tmp_path / "d.npy", depth)
    code = f"""
import sys
import cuboidcli as cb
assert "torch" not in sys.modules and "numpy" not in sys.modules, "import cuboidcli pulled in heavy modules"
res = cb.fit(cb.read_depth({str(tmp_path / "d.npy")!r}), cb.Camera(65, 65, 40, 30), hypotheses=32,
             max_cuboids=2, device="cpu")
res.overlay(); res.save_json({str(tmp_path / "r.json")!r}); res.labels
loaded = sorted(m for m in ("typer", "rich", "click") if m in sys.modules)
assert not loaded, loaded
"""
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=ROOT, timeout=300)
    assert proc.returncode == 0, proc.stderr[-2000:]
    assert json.loads((tmp_path / "r.json").read_text())["schema"] == "cuboids/1"


def test_a_12_megapixel_frame_is_fitted_on_the_papers_4800_points(room_depth, nyu_camera, room_result):
    """The fitting grid follows the frame's size: a 4032x3024 depth map of the same room gives the 60x80
    grid's 4800 points (not 190,000 at a fixed step of 8) and the same walls and floor."""
    import cv2

    depth, _ = room_depth
    big = cv2.resize(depth, (4032, 3024), interpolation=cv2.INTER_NEAREST)
    cam = nyu_camera.scaled(4032 / 640)
    res = cb.fit(big, cb.Camera(cam.fx, cam.fy, cam.cx, cam.cy), seed=0, **QUICK)
    assert res.info.grid_step == 51 and res.grid_labels.shape == (60, 80)
    assert res.info.n_points <= 4800 and room_result.info.grid_step == 8  # the room leaves some cells empty
    assert res.info.n_points == pytest.approx(room_result.info.n_points, rel=0.02)
    centers = np.array([c.center for c in res.cuboids])
    assert np.any(np.abs(centers[:, 2] - 4.5) < 0.1) and np.any(np.abs(centers[:, 1] - 1.4) < 0.1)
    # an explicit step still wins
    assert FitConfig(grid_step=8).step_for(3024, 4032) == 8


def test_a_photo_gets_its_camera_from_exif_and_a_warning_without_one(tmp_path):
    """Fitter.fit on a photo's path: a photo with a 35 mm equivalent focal length gets fx from it; one
    without any camera information is fitted with the default field of view and one InputWarning."""
    import warnings

    from PIL import Image

    from cuboidcli.io.depth import InputWarning

    rgb = (np.random.default_rng(0).uniform(0, 255, (120, 160, 3))).astype(np.uint8)
    exif = Image.Exif()
    exif.get_ifd(0x8769)[41989] = 28
    Image.fromarray(rgb).save(tmp_path / "exif.jpg", exif=exif)
    Image.fromarray(rgb).save(tmp_path / "bare.jpg")
    fitter = cb.Fitter(hypotheses=64, max_cuboids=1, align="free", theta=-1e9, device="cpu")
    with warnings.catch_warnings():
        warnings.simplefilter("error")
        res = fitter.fit(tmp_path / "exif.jpg")
    assert res.camera.fx == pytest.approx(28 / 36 * 160) and res.camera.cx == 79.5
    assert res.record.input["intrinsics_source"] == "exif: FocalLengthIn35mmFilm 28 mm"
    with pytest.warns(InputWarning, match="63 degree field of view") as caught:
        bare = fitter.fit(tmp_path / "bare.jpg")
    assert len(caught) == 1 and len(bare.cuboids) == 1
    assert bare.record.input["intrinsics_source"].startswith("default:")


def test_a_rooms_objects_in_words_count_its_doors_and_sinks():
    from cuboidcli.fitting.objects import SceneObject
    from cuboidcli.result import objects_summary

    box = cb.Cuboid(np.zeros(3), np.ones(3), np.eye(3))

    def objects(*kinds):
        return [SceneObject(box, (), 10, 0.5, kind) for kind in kinds]

    assert objects_summary([]) == "0 objects"
    assert objects_summary(objects("object")) == "1 object"
    assert objects_summary(objects("object", "door", "object")) == "3 objects (1 door)"
    assert objects_summary(objects("sink", "door", "door", "object")) == "4 objects (2 doors, 1 sink)"

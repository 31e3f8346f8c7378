"""cuboidcli.load.frame: one frame's inputs (depth and/or RGB, intrinsics, depth scale) as a FrameData
(the camera and depth scale resolved by cuboidcli.load.camera), and a fit packaged as a FitResult with its
settings and fit_info (cuboidcli.result.result_record)."""

from __future__ import annotations

import json
import math
from dataclasses import replace

import cv2
import numpy as np
import pytest

from cuboidcli.camera import PRESETS, Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.factories import DepthModelOptions, depth_estimator
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import FitInfo
from cuboidcli.geometry.gravity import given_gravity
from cuboidcli.io.depth import InputError
from cuboidcli.io.photo import DEFAULT_FOV_DEG
from cuboidcli.io.result import read_result, same_settings, write_result
from cuboidcli.load import Input
from cuboidcli.load.camera import resolve_depth_scale
from cuboidcli.load.frame import load_frame
from cuboidcli.result import result_record

H, W = 48, 64
SPEC = "200,210,31.5,23.5"


def _units() -> np.ndarray:
    """A depth map in PNG units (H, W) uint16: a ramp 1000-3000 with a hole in the corner."""
    units = np.tile(np.linspace(1000, 3000, W), (H, 1)).astype(np.uint16)
    units[:6, :8] = 0
    return units


@pytest.fixture()
def depth_png(tmp_path):
    path = tmp_path / "room_depth.png"
    cv2.imwrite(str(path), _units())
    return path


@pytest.fixture()
def rgb_png(tmp_path):
    bgr = np.zeros((H, W, 3), np.uint8)
    bgr[..., 0], bgr[..., 1], bgr[..., 2] = 10, 20, 30  # blue, green, red as cv2 stores them
    bgr[:, : W // 2, 2] = 200  # a red left half, so that the network sees some structure
    path = tmp_path / "room_rgb.png"
    cv2.imwrite(str(path), bgr)
    return path


def test_a_depth_map_with_intrinsics(depth_png):
    frame = load_frame(depth_png, intrinsics=SPEC)
    assert frame.depth_m.dtype == np.float32 and frame.depth_m.shape == (H, W)
    assert np.array_equal(frame.depth_m, _units().astype(np.float32) * np.float32(0.001))
    assert frame.camera == Camera(200.0, 210.0, 31.5, 23.5, W, H)  # the size comes from the depth map
    assert frame.rgb is None and frame.depth_seconds is None
    assert frame.notes == []
    assert frame.meta == {
        "depth": str(depth_png),
        "image": None,
        "depth_source": "depth map",
        "depth_scale": 0.001,
        "width": W,
        "height": H,
        "valid_fraction": round(1 - 48 / (H * W), 6),
        "intrinsics_source": "command line",
    }


def test_without_intrinsics_a_default_field_of_view_is_assumed_and_the_user_told(tmp_path):
    units = cv2.resize(_units(), (640, 480), interpolation=cv2.INTER_NEAREST)
    cv2.imwrite(str(tmp_path / "full.png"), units)
    frame = load_frame(tmp_path / "full.png")
    fx = 320.0 / math.tan(math.radians(DEFAULT_FOV_DEG / 2))
    assert frame.camera == Camera(fx, fx, 319.5, 239.5, 640, 480)
    assert frame.meta["intrinsics_source"].startswith("default:")
    assert len(frame.notes) == 1 and frame.notes[0].startswith(
        "no camera intrinsics (no -K, --camera or EXIF"
    )
    tum = load_frame(tmp_path / "full.png", preset="tum")  # a preset brings its depth unit: 1/5000 m
    assert tum.camera == Camera.preset("tum") and tum.notes == []
    assert tum.meta["depth_scale"] == PRESETS["tum"]["depth_scale"]
    assert tum.meta["intrinsics_source"] == "preset:tum"
    assert np.allclose(tum.depth_m, units / 5000.0, rtol=1e-6)
    # intrinsics given in a file for another image size but plausible for this one are used as they are,
    # with a note
    shifted = tmp_path / "cam.json"
    shifted.write_text(
        json.dumps({"fx": 200.0, "fy": 210.0, "cx": 31.5, "cy": 23.5, "width": 640, "height": 480})
    )
    small = load_frame(_small(tmp_path), intrinsics=str(shifted))
    assert small.camera == Camera(200.0, 210.0, 31.5, 23.5, W, H)
    assert small.notes == [f"intrinsics are for 640x480 but the depth map is {W}x{H}; using them unscaled"]


def test_a_preset_is_scaled_to_an_image_of_its_aspect_ratio_and_refused_for_another(tmp_path):
    units = cv2.resize(_units(), (1280, 960), interpolation=cv2.INTER_NEAREST)
    cv2.imwrite(str(tmp_path / "big.png"), units)
    big = load_frame(tmp_path / "big.png", preset="nyu")
    nyu = Camera.preset("nyu")
    assert big.camera.fx == pytest.approx(1037.7158) and big.camera.fy == pytest.approx(2 * nyu.fy)
    assert big.camera.cx == pytest.approx(2 * nyu.cx + 0.5) and big.camera.cy == pytest.approx(
        2 * nyu.cy + 0.5
    )
    assert big.meta["intrinsics_source"] == "preset:nyu scaled to 1280x960" and big.notes == []
    small = load_frame(_small(tmp_path), preset="nyu")  # 64x48: a tenth
    assert small.camera.fx == pytest.approx(nyu.fx / 10)
    square = cv2.resize(_units(), (1000, 1000), interpolation=cv2.INTER_NEAREST)
    cv2.imwrite(str(tmp_path / "square.png"), square)
    with pytest.raises(
        InputError,
        match=r"--camera nyu is for 640x480 images \(aspect 1.333\) but this "
        r"image is 1000x1000 \(aspect 1.000\); give its intrinsics with -K fx,fy,cx,cy",
    ):
        load_frame(tmp_path / "square.png", preset="nyu")
    # -K wins over a preset, which then only gives the depth unit
    both = load_frame(tmp_path / "square.png", preset="tum", intrinsics="800,800,499.5,499.5")
    assert both.camera.fx == 800.0 and both.meta["depth_scale"] == PRESETS["tum"]["depth_scale"]


def _small(tmp_path):
    path = tmp_path / "small_depth.png"
    cv2.imwrite(str(path), _units())
    return path


def test_depth_scale_option_beats_the_intrinsics_file_which_beats_the_preset():
    with_scale = Camera(1.0, 1.0, 0.0, 0.0, depth_scale=0.0002)
    without = Camera(1.0, 1.0, 0.0, 0.0)
    assert resolve_depth_scale(0.0005, with_scale, "tum") == 0.0005
    assert resolve_depth_scale(None, with_scale, "scannet") == 0.0002
    assert resolve_depth_scale(None, without, "tum") == pytest.approx(0.0002)
    assert resolve_depth_scale(None, without, None) == 0.001
    assert resolve_depth_scale(None, None, None) == 0.001  # no intrinsics given at all
    for bad in (0.0, -0.001):
        with pytest.raises(InputError, match=rf"--depth-scale must be positive \(got {bad}\)"):
            resolve_depth_scale(bad, with_scale, None)


def test_a_cameras_json_gives_intrinsics_and_depth_scale_per_frame(tmp_path):
    units = _units() // 2  # half a millimetre per unit
    cv2.imwrite(str(tmp_path / "b_depth.png"), units)
    cams = {
        "a": {"fx": 100.0, "fy": 100.0, "cx": 31.5, "cy": 23.5, "width": W, "height": H},
        "b": {
            "fx": 150.0,
            "fy": 160.0,
            "cx": 30.0,
            "cy": 20.0,
            "width": W,
            "height": H,
            "depth_scale": 0.0005,
        },
    }
    (tmp_path / "cameras.json").write_text(json.dumps(cams))
    spec = str(tmp_path / "cameras.json")
    frame = load_frame(tmp_path / "b_depth.png", intrinsics=spec)  # the name "b" comes from "b_depth"
    assert frame.camera == Camera(150.0, 160.0, 30.0, 20.0, W, H) and frame.meta["depth_scale"] == 0.0005
    assert np.array_equal(frame.depth_m, units.astype(np.float32) * np.float32(0.0005))
    assert frame.meta["intrinsics_source"] == spec and frame.notes == []
    other = load_frame(tmp_path / "b_depth.png", intrinsics=spec, frame_name="a", depth_scale=0.001)
    assert other.camera.fx == 100.0 and other.meta["depth_scale"] == 0.001
    with pytest.raises(InputError, match="holds intrinsics for several frames .*none is named 'c'"):
        load_frame(tmp_path / "b_depth.png", intrinsics=spec, frame_name="c")


def test_rgb_is_read_as_rgb_and_must_match_the_depth_map(tmp_path, depth_png, rgb_png):
    frame = load_frame(depth_png, rgb_png, intrinsics=SPEC)
    assert frame.rgb.shape == (H, W, 3) and frame.rgb.dtype == np.uint8
    assert frame.rgb[0, -1].tolist() == [30, 20, 10]  # red, green, blue
    assert frame.meta["image"] == str(rgb_png) and frame.meta["depth_source"] == "depth map"
    small = tmp_path / "small.png"
    cv2.imwrite(str(small), np.zeros((24, 32, 3), np.uint8))
    with pytest.raises(
        InputError, match=f"RGB image is 32x24 but the depth map is {W}x{H}; they must be registered"
    ):
        load_frame(depth_png, small, intrinsics=SPEC)


def test_an_rgb_image_alone_gets_its_depth_from_the_built_in_network(rgb_png):
    frame = load_frame(None, rgb_png, intrinsics=SPEC)
    assert frame.depth_m.shape == (H, W) and (frame.depth_m > 0).all()
    assert frame.camera == Camera(200.0, 210.0, 31.5, 23.5, W, H) and frame.rgb.shape == (H, W, 3)
    assert frame.meta["depth"] is None and frame.meta["image"] == str(rgb_png)
    assert frame.meta["depth_source"].startswith("depth estimated from RGB by the built-in network")
    assert frame.meta["valid_fraction"] == 1.0
    assert frame.depth_seconds is not None and frame.depth_seconds > 0
    # the network is built once per process and options
    assert depth_estimator(DepthModelOptions()) is depth_estimator(DepthModelOptions())


@pytest.mark.parametrize(
    "options, message",
    [
        (DepthModelOptions(model="missing.pt"), "depth weights missing.pt not found"),
        (DepthModelOptions(model="model.tflite"), "expected an .onnx file"),
        (DepthModelOptions(kind="relative"), "the built-in depth network predicts metric depth"),
        (DepthModelOptions(model="missing.onnx"), "depth model missing.onnx not found"),
    ],
)
def test_depth_model_problems_are_input_errors(rgb_png, options, message):
    with pytest.raises(InputError, match=message):
        load_frame(None, rgb_png, intrinsics=SPEC, depth_model=options)


def test_unusable_inputs_are_one_line_input_errors(tmp_path, depth_png):
    zeros = tmp_path / "zeros.png"
    cv2.imwrite(str(zeros), np.zeros((H, W), np.uint16))
    cases = [
        (
            dict(depth_path=depth_png, preset="kinect9"),
            "unknown --camera 'kinect9'; choose one of: nyu, tum, scannet",
        ),
        (dict(depth_path=None), r"give a depth map \(--depth D.png\) or an RGB image"),
        (dict(depth_path=tmp_path / "nope.png"), "depth file not found"),
        (dict(depth_path=zeros), "the depth map has no valid pixels"),
        (dict(depth_path=depth_png, depth_scale=1.0), r"median depth is \d+ m: the depth unit looks wrong"),
        (dict(depth_path=depth_png, intrinsics="5,5,31.5,23.5"), "looks like a focal length in millimetres"),
        (
            dict(depth_path=depth_png, intrinsics="200,210,500,23.5"),
            r"principal point \(500, 23.5\) is far outside",
        ),
        (dict(depth_path=depth_png, intrinsics="200,210"), "give fx,fy,cx,cy in pixels"),
    ]
    for kwargs, message in cases:
        with pytest.raises(InputError, match=message) as caught:
            load_frame(**kwargs)
        assert "\n" not in str(caught.value)


def _info(**kwargs) -> FitInfo:
    info = FitInfo(
        gains=[120.0, 45.5],
        theta=41.4,
        n_points=1000,
        iterations=3,
        batches=[1, 2, 0],
        stop_reason="gain_below_theta",
        rejected_gain=12.0,
        timing_s={"sample": 0.2, "total": 0.5},
        align="manhattan",
        aligned=["manhattan", "gravity"],
        random_generator="numpy",
        backend_used="numba",
        warnings=["only 0.5 % of depth pixels are valid"],
    )
    return replace(info, **kwargs)


def frame_result(camera, cuboids, info, config, meta, solver_name, sampler_name, extra=None):
    """The record of a frame fitted with ``config``, as :class:`cuboidcli.api.Fitter` makes it."""
    inp = Input("depth", camera, meta, depth_m=np.zeros((camera.height, camera.width), np.float32))
    return result_record(inp, cuboids, info, config, solver_name, sampler_name, extra or {})


def test_frame_result_records_the_settings_and_what_happened():
    camera = Camera(200.0, 210.0, 31.5, 23.5, W, H)
    cuboids = [Cuboid([0.0, 0.0, 2.0], [0.5, 0.4, 0.3], np.eye(3))]
    config = FitConfig(max_cuboids=5, seed=3)
    meta = {"depth": "d.png", "width": W}
    info = _info()
    result = frame_result(camera, cuboids, info, config, meta, "numerical", "sequential", {"weights": "w.pt"})
    assert result.camera == camera and result.cuboids == cuboids and result.input == meta
    assert result.timing_s == {"sample": 0.2, "total": 0.5}
    assert result.settings == {
        **config.to_dict("frame"),
        "theta_used": 41.4,
        "random_generator": "numpy",
        "backend_used": "numba",
        "solver_name": "numerical",
        "sampler_name": "sequential",
        "weights": "w.pt",
    }
    assert result.extras == {
        "fit_info": {
            "n_points": 1000,
            "grid_step": 8,
            "iterations": 3,
            "batches": [1, 2, 0],
            "stop_reason": "gain_below_theta",
            "rejected_gain": 12.0,
            "gains": [120.0, 45.5],
            "align": "manhattan",
            "aligned": ["manhattan", "gravity"],
            "warnings": ["only 0.5 % of depth pixels are valid"],
        }
    }
    # with a gravity estimate the result carries it and the camera pose it gives
    gravity = given_gravity([0.0, 2.0, 0.0])
    levelled = frame_result(camera, cuboids, _info(gravity=gravity), config, meta, "numerical", "sequential")
    assert levelled.extras["gravity"] == gravity.to_dict()
    assert np.allclose(levelled.extras["world_from_camera"], gravity.world_from_camera())
    assert "weights" not in levelled.settings
    # a frame's settings leave out those only a room reads
    assert not {"voxel_m", "visibility", "up", "virtual_view_m"} & set(result.settings)


def test_same_settings_compares_a_saved_result_with_a_configuration(tmp_path):
    camera = Camera(200.0, 210.0, 31.5, 23.5, W, H)
    config = FitConfig(max_cuboids=5)
    result = frame_result(camera, [], _info(), config, {}, "numerical", "sequential", {"weights": "w.pt"})
    write_result(tmp_path / "r.json", result)
    saved = read_result(tmp_path / "r.json").settings
    assert same_settings(saved, config, {"weights": "w.pt"})
    assert same_settings(saved, config)  # the weights were not asked about
    assert not same_settings(saved, replace(config, max_cuboids=6), {"weights": "w.pt"})
    assert not same_settings(saved, replace(config, local_radii_m=(0.2, 0.4)), {"weights": "w.pt"})
    assert not same_settings(saved, config, {"weights": "other.pt"})
    # A result written before a setting existed was fitted with that setting's default.
    older = {k: v for k, v in saved.items() if k != "refine_iters"}
    assert same_settings(older, config)
    assert not same_settings(older, replace(config, refine_iters=3))


def test_dropping_depth_edges_leaves_out_the_estimates_pixels_on_discontinuities():
    """--drop-depth-edges: the estimate from a real NYU photo loses some of its pixels (set to 0, counted in
    meta: 0.26 % with the smooth depth_v4, 4 % of the real frames with depth_v3); by default nothing is
    dropped."""
    from tests.conftest import SHARED_DATA

    photo = SHARED_DATA / "nyu" / "basement_00050_rgb.jpg"
    if not photo.is_file():
        pytest.skip("needs ../shared/data (the real NYU frames)")
    kept = load_frame(None, photo, preset="nyu", depth_model=DepthModelOptions())
    dropped = load_frame(None, photo, preset="nyu", depth_model=DepthModelOptions(drop_edges=True))
    assert "depth_edges_dropped" not in kept.meta and (kept.depth_m > 0).all()
    share = dropped.meta["depth_edges_dropped"]
    assert 0.001 < share < 0.2
    assert (dropped.depth_m == 0).mean() == pytest.approx(share, abs=1e-3)
    same = dropped.depth_m > 0
    assert np.array_equal(dropped.depth_m[same], kept.depth_m[same])

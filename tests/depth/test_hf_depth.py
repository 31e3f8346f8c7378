"""Hugging Face transformers depth models (cuboidcli.depth.hf): tiny random models of each supported
architecture, saved with save_pretrained in a tmp folder (tests/depth/conftest.py), loaded offline."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.depth import estimate_depth
from cuboidcli.depth.hf import HFDepthEstimator, is_hf_model
from cuboidcli.factories import DepthModelOptions, depth_estimator, make_depth_estimator

pytest.importorskip("transformers")
pytestmark = pytest.mark.usefixtures("one_thread")

H, W = 45, 70  # not square, not a multiple of any patch size
CAMERA = Camera(fx=60.0, fy=60.0, cx=34.5, cy=22.0, width=W, height=H)
METRIC = ("da_metric", "glpn", "zoedepth", "depth_pro")
RELATIVE = ("da_relative", "dpt")


@pytest.fixture(scope="module")
def rgb() -> np.ndarray:
    img = np.random.default_rng(0).integers(0, 256, (H, W, 3), dtype=np.uint8)
    img[..., 0] = np.linspace(20, 240, W).astype(np.uint8)[None, :]
    return img


def one_line(info) -> str:
    text = str(info.value)
    assert "\n" not in text and text
    return text


@pytest.mark.parametrize("name", METRIC)
def test_metric_models_predict_the_full_image(hf_models, rgb, name):
    est = make_depth_estimator(hf_models[name])
    assert isinstance(est, HFDepthEstimator) and est.kind == "metric"
    depth = est.predict(rgb, CAMERA)
    assert depth.shape == (H, W) and depth.dtype == np.float32
    assert np.isfinite(depth).all() and (depth > 0).mean() > 0.9
    assert est.predicts_focal == (name == "depth_pro")
    assert name.split("_")[0] in est.describe() and "metric" in est.describe()


@pytest.mark.parametrize("name", RELATIVE)
def test_relative_models_need_a_scale(hf_models, rgb, name):
    with pytest.raises(ValueError, match="only up to scale") as info:
        make_depth_estimator(hf_models[name])
    assert "camera's height" in one_line(info)
    est = make_depth_estimator(hf_models[name], scale=2.0, shift=0.1)
    assert est.kind == "relative-inverse" and not est.predicts_focal
    raw = est.raw_output(rgb, CAMERA)
    depth = est.predict(rgb, CAMERA)
    assert depth.shape == (H, W) and depth.dtype == np.float32
    expected = 1.0 / (2.0 * raw + 0.1)
    ok = np.isfinite(expected) & (expected > 0)
    np.testing.assert_allclose(depth[ok], expected[ok], rtol=1e-5)
    assert np.all(depth[~ok] == 0)
    assert "scale 2" in est.describe()


def test_relative_model_aligned_to_partial_depth(hf_models, rgb):
    est = make_depth_estimator(hf_models["da_relative"], ref_depth=np.full((H, W), np.nan))
    raw = est.raw_output(rgb, CAMERA)
    truth = 1.0 / (0.5 * raw + (0.2 - 0.5 * raw.min()))  # positive inverse depth
    partial = np.where(np.random.default_rng(2).random((H, W)) < 0.2, truth, 0.0)
    estimator = make_depth_estimator(hf_models["da_relative"], ref_depth=partial)
    depth, text = estimate_depth(estimator, rgb, CAMERA)
    np.testing.assert_allclose(depth, truth, rtol=1e-4)
    assert "aligned to the partial depth map" in text


def test_relative_model_with_camera_height_is_accepted(hf_models, rgb):
    """Accepted at construction; a random network's output has no floor, so the prediction says so."""
    est = make_depth_estimator(hf_models["dpt"], camera_height_m=1.4)
    assert "1.4 m above the floor" in est.describe()
    with pytest.raises(ValueError, match="no floor found") as info:
        est.predict(rgb, CAMERA)
    one_line(info)


def test_kind_overrides(hf_models, rgb):
    est = make_depth_estimator(hf_models["dpt"], kind="metric")  # a DPT fine-tuned on NYU/KITTI
    assert est.kind == "metric" and est.predict(rgb, CAMERA).shape == (H, W)
    assert make_depth_estimator(hf_models["glpn"], kind="relative", scale=2.0).kind == "relative"
    with pytest.raises(ValueError, match="predicts relative-inverse depth") as info:
        make_depth_estimator(hf_models["da_relative"], kind="metric")
    one_line(info)
    with pytest.raises(ValueError, match="does not apply"):
        make_depth_estimator(hf_models["zoedepth"], kind="relative-inverse", scale=1.0)
    with pytest.raises(ValueError, match="needs no scale"):
        make_depth_estimator(hf_models["glpn"], scale=2.0)


def test_depth_pro_focal(hf_models, rgb):
    est = make_depth_estimator(hf_models["depth_pro"])
    depth, focal = est.predict_with_focal(rgb)
    assert depth.shape == (H, W) and depth.dtype == np.float32 and (depth > 0).all()
    assert math.isfinite(focal) and focal > 0
    # with the camera it predicted, predict() gives the same map; a known focal length rescales the
    # canonical inverse depth by W / f, so depth is proportional to the focal length (up to resampling)
    cam = Camera(focal, focal, (W - 1) / 2, (H - 1) / 2, W, H)
    np.testing.assert_allclose(est.predict(rgb, cam), depth, rtol=1e-5)
    longer = est.predict(rgb, Camera(2 * focal, 2 * focal, (W - 1) / 2, (H - 1) / 2, W, H))
    np.testing.assert_allclose(np.median(longer / depth), 2.0, rtol=0.02)
    with pytest.raises(ValueError, match="does not predict the focal length"):
        make_depth_estimator(hf_models["glpn"]).predict_with_focal(rgb)


def test_other_estimators_do_not_predict_focal(hf_models):
    from cuboidcli.depth import BuiltinDepthEstimator, OnnxDepthEstimator

    assert BuiltinDepthEstimator.predicts_focal is False and OnnxDepthEstimator.predicts_focal is False


def test_missing_hub_model_offline(tmp_path):
    from huggingface_hub import constants

    with pytest.raises(ValueError) as info:
        make_depth_estimator("hf:some-owner/missing-depth-model")
    text = one_line(info)
    assert "some-owner/missing-depth-model" in text and str(constants.HF_HUB_CACHE) in text
    assert "HF_HUB_OFFLINE" in text and "model id" in text
    with pytest.raises(ValueError, match="hf:owner/name"):
        make_depth_estimator("hf:")


def test_folders_that_are_not_depth_models(hf_models, tmp_path):
    (tmp_path / "empty").mkdir()
    with pytest.raises(ValueError, match="has no config.json") as info:
        make_depth_estimator(tmp_path / "empty")
    one_line(info)
    with pytest.raises(ValueError, match="bert model .* not a supported depth-estimation model") as info:
        make_depth_estimator(hf_models["bert"])
    one_line(info)
    assert is_hf_model(tmp_path) and is_hf_model("hf:a/b") and not is_hf_model("m.onnx")
    assert not is_hf_model(None)


def test_folder_without_processor(hf_models, tmp_path):
    import shutil

    shutil.copytree(hf_models["glpn"], tmp_path / "glpn")
    (tmp_path / "glpn" / "preprocessor_config.json").unlink()
    with pytest.raises(ValueError, match="image processor") as info:
        make_depth_estimator(tmp_path / "glpn")
    one_line(info)


def test_onnx_options_refused_for_hf_models(hf_models):
    with pytest.raises(ValueError, match="apply to an .onnx depth model only"):
        make_depth_estimator(hf_models["glpn"], onnx_preset="depth-anything-v2")


def test_options_are_hashable_and_built_once(hf_models):
    opts = DepthModelOptions(model=hf_models["da_relative"], camera_height_m=1.5)
    again = DepthModelOptions(model=hf_models["da_relative"], camera_height_m=1.5)
    assert hash(opts) == hash(again)
    assert depth_estimator(opts) is depth_estimator(again)
    assert depth_estimator(DepthModelOptions(model=hf_models["glpn"])).kind == "metric"

"""Edges of cuboidcli.depth.hf: Depth Pro's focal length from its field of view, the camera it assumes
(principal point at the image centre), its clamped inverse depth; the torch steps that stand in for
transformers' processors without torchvision (ZoeDepth's padding cut, Depth Pro's preprocessing); and
the one-line loading errors. Tiny random models from tests/depth/conftest.py; nothing downloaded."""

from __future__ import annotations

import importlib.util
import json
import math
import shutil
from types import SimpleNamespace

import numpy as np
import pytest

from cuboidcli.depth.hf import HFDepthEstimator, _DepthProPlainProcessor, _zoe_post_process
from cuboidcli.factories import make_depth_estimator

torch = pytest.importorskip("torch")
pytest.importorskip("transformers")
pytestmark = pytest.mark.usefixtures("one_thread")

H, W = 30, 40


@pytest.fixture(scope="module")
def rgb() -> np.ndarray:
    img = np.random.default_rng(2).integers(0, 256, (H, W, 3), dtype=np.uint8)
    img[..., 1] = np.linspace(0, 255, W).astype(np.uint8)[None, :]
    return img


@pytest.fixture(scope="module")
def depth_pro(hf_models):
    return make_depth_estimator(hf_models["depth_pro"])


def fov(deg: float):
    return SimpleNamespace(field_of_view=torch.tensor([deg]))


def test_focal_length_from_the_field_of_view(depth_pro):
    assert depth_pro._predicted_focal(fov(90.0), 40) == pytest.approx(20.0)  # 0.5 W / tan(45 deg)
    assert depth_pro._predicted_focal(fov(60.0), 40) == pytest.approx(20.0 * math.sqrt(3))
    assert depth_pro._predicted_focal(fov(170.0), 2) == pytest.approx(math.tan(math.radians(5)))  # short
    for bad in (200.0, float("nan"), -30.0):  # past 180 degrees the focal length comes out negative
        with pytest.raises(ValueError, match="unusable field of view"):
            depth_pro._predicted_focal(fov(bad), 40)
    with pytest.raises(ValueError, match="does not predict the field of view"):
        depth_pro._predicted_focal(SimpleNamespace(), 40)


def test_predicted_camera_has_its_principal_point_at_the_centre(depth_pro, rgb, monkeypatch):
    out = depth_pro._forward(rgb)
    focal = depth_pro._predicted_focal(out, W)
    seen = []
    to_metres = depth_pro.scaling.to_metres
    monkeypatch.setattr(
        depth_pro.scaling, "to_metres", lambda raw, cam: seen.append(cam) or to_metres(raw, cam)
    )
    depth, f = depth_pro.predict_with_focal(rgb)
    assert f == pytest.approx(focal)
    (cam,) = seen
    assert (cam.fx, cam.fy) == pytest.approx((focal, focal))
    assert (cam.cx, cam.cy) == (19.5, 14.5) and (cam.width, cam.height) == (W, H)
    assert depth.shape == (H, W)


def test_inverse_depth_is_rescaled_by_width_over_focal_and_clamped(depth_pro):
    # the canonical inverse depth, 2x2 blocks averaged by the half-size bilinear resize
    block = np.array([[0.5, 0.0], [1e6, -3.0]])
    pred = np.kron(block, np.ones((2, 2)))
    pred[0, 0], pred[1, 1] = 0.6, 0.4  # still 0.5 on average
    out = SimpleNamespace(predicted_depth=torch.tensor(pred[None], dtype=torch.float32))
    depth = depth_pro._depth_pro_depth(out, (2, 2), 4.0)  # W / f = 0.5
    # 1 / 0.25; inverse depth 0 or negative -> 1e4 m; beyond 1e4 (1e6 * 0.5) -> 1e-4 m
    np.testing.assert_allclose(depth, [[4.0, 1e4], [1e-4, 1e4]], rtol=1e-6)
    # without a focal length the predicted field of view gives it: 90 deg over 2 pixels = 1 px, W / f = 2
    out.field_of_view = torch.tensor([90.0])
    np.testing.assert_allclose(
        depth_pro._depth_pro_depth(out, (2, 2), None), [[1.0, 1e4], [1e-4, 1e4]], rtol=1e-6
    )


def test_depth_pro_without_its_field_of_view_head(hf_models, tmp_path, rgb):
    folder = tmp_path / "no_fov"
    shutil.copytree(hf_models["depth_pro"], folder)
    cfg = json.loads((folder / "config.json").read_text())
    cfg["use_fov_model"] = False
    (folder / "config.json").write_text(json.dumps(cfg))
    est = make_depth_estimator(folder)
    assert est.predicts_focal is False
    with pytest.raises(ValueError, match="does not predict the focal length"):
        est.predict_with_focal(rgb)
    # the processor built without torchvision reads the model's preprocessor_config.json
    if isinstance(est.processor, _DepthProPlainProcessor):
        assert est.processor.size == (64, 64)
    assert est.describe() == "depth estimated from RGB by no_fov (depth_pro, metric)"


def test_zoedepth_padding_is_cut_at_the_source_size():
    # an image of 32 x 50 is padded by int(sqrt(side / 2) * 3) per side: 12 rows, 15 columns
    rng = np.random.default_rng(0)
    padded = np.full((56, 80), 100.0)
    inner = rng.uniform(1, 5, (32, 50))
    padded[12:44, 15:65] = inner
    pred = torch.tensor(padded[None], dtype=torch.float32)
    np.testing.assert_allclose(_zoe_post_process(pred, (32, 50), True).numpy(), inner, rtol=1e-5)
    # without padding a prediction at the image's size passes unchanged
    np.testing.assert_allclose(_zoe_post_process(pred, (56, 80), False).numpy(), padded, rtol=1e-5)


def test_depth_pro_plain_preprocessing():
    grey = np.full((2, 2, 3), 51, np.uint8)  # 0.2 after the default rescale 1 / 255
    x = _DepthProPlainProcessor({})(grey)["pixel_values"]
    assert x.shape == (1, 3, 1536, 1536)  # Depth Pro's own input size when the config gives none
    np.testing.assert_allclose(x[0, :, ::500, ::500].numpy(), -0.6, rtol=1e-5)  # (0.2 - 0.5) / 0.5
    img = np.arange(4 * 6 * 3, dtype=np.uint8).reshape(4, 6, 3)
    plain = {"size": {"height": 2, "width": 3}, "do_rescale": False, "do_normalize": False}
    x = _DepthProPlainProcessor(plain)(img)["pixel_values"][0].numpy()
    blocks = img.astype(np.float64).reshape(2, 2, 3, 2, 3).mean(axis=(1, 3)).transpose(2, 0, 1)
    np.testing.assert_allclose(x, blocks, rtol=1e-6)  # halved: the mean of each 2 x 2 block
    cfg = plain | {"do_rescale": True, "rescale_factor": 0.5, "do_normalize": True}
    cfg |= {"image_mean": [1.0, 2.0, 3.0], "image_std": [2.0, 4.0, 8.0]}
    x = _DepthProPlainProcessor(cfg)(img)["pixel_values"][0].numpy()
    mean, std = np.array([1.0, 2.0, 3.0])[:, None, None], np.array([2.0, 4.0, 8.0])[:, None, None]
    np.testing.assert_allclose(x, (0.5 * blocks - mean) / std, rtol=1e-6)


def cause_first_line(info) -> str:
    return str(info.value.__cause__).strip().splitlines()[0]


def test_loading_errors_quote_the_cause(hf_models, tmp_path):
    broken = tmp_path / "broken"
    shutil.copytree(hf_models["glpn"], broken)
    (broken / "config.json").write_text("{ not json")
    with pytest.raises(ValueError, match=f"cannot load the Hugging Face model in {broken}: ") as info:
        make_depth_estimator(broken)
    assert cause_first_line(info) in str(info.value)
    # a processor that only exists for torchvision, on another architecture than Depth Pro
    wrong = tmp_path / "wrong_processor"
    shutil.copytree(hf_models["glpn"], wrong)
    if importlib.util.find_spec("torchvision") is None:
        processor = {"image_processor_type": "DepthProImageProcessor"}
        (wrong / "preprocessor_config.json").write_text(json.dumps(processor))
        with pytest.raises(ValueError, match="its image processor needs torchvision") as info:
            HFDepthEstimator(wrong)
        assert cause_first_line(info) in str(info.value)
    (wrong / "preprocessor_config.json").unlink()
    with pytest.raises(ValueError, match=r"has no usable image processor \(preprocessor_config.json\)"):
        HFDepthEstimator(wrong)


def test_model_names_and_types_in_messages(hf_models):
    with pytest.raises(ValueError, match="expected hf:owner/name"):
        HFDepthEstimator("hf:a/b/c")
    with pytest.raises(ValueError, match=r"is a bert model \(BertModel\), not a supported"):
        HFDepthEstimator(hf_models["bert"])

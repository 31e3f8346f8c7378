"""ONNX conventions: named presets (layout, normalisation, size multiple, kind), NHWC inputs, and the
load-time checks of inputs and outputs; tiny torch modules exported to ONNX in a tmp folder."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch
from torch import nn

from cuboidcli.camera import Camera
from cuboidcli.depth import OnnxDepthEstimator
from cuboidcli.depth.onnx_presets import PRESETS, get_preset, input_size
from cuboidcli.factories import DepthModelOptions, depth_estimator, make_depth_estimator

pytest.importorskip("onnxruntime")
pytestmark = pytest.mark.usefixtures("one_thread")

H, W = 60, 80
CAMERA = Camera(fx=80.0, fy=80.0, cx=39.5, cy=29.5, width=W, height=H)


class MeanRed(nn.Module):
    """NCHW: output (1, 1, h, w) = the red input channel + 3 (positive for normalised inputs)."""

    def forward(self, x):
        return x[:, :1] + 3.0


class MeanRedNHWC(nn.Module):
    """NHWC: (1, h, w, 3) -> (1, h, w) = red + 3."""

    def forward(self, x):
        return x[..., 0] + 3.0


class WrongOutput(nn.Module):
    def forward(self, x):
        return x[:, :1].mean(dim=(2, 3))  # (1, 1): not a map


def export(module, path, shape, dynamic_axes=None, inputs=1):
    args = tuple(torch.rand(*shape) for _ in range(inputs))
    names = [f"in{i}" for i in range(inputs)]
    axes = None
    if dynamic_axes:
        axes = {n: dynamic_axes for n in names} | {"depth": {}}
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        torch.onnx.export(module, args, str(path), input_names=names, output_names=["depth"],
                          dynamic_axes=axes, opset_version=17, dynamo=False)  # fmt: skip
    return path


@pytest.fixture(scope="module")
def models(tmp_path_factory):
    root = tmp_path_factory.mktemp("presets")

    class TwoInputs(nn.Module):
        def forward(self, x, y):
            return x[:, :1] + y[:, :1]

    return {
        "nchw_dynamic": export(MeanRed(), root / "a.onnx", (1, 3, 28, 42), {2: "h", 3: "w"}),
        "nchw_fixed": export(MeanRed(), root / "b.onnx", (1, 3, 28, 42)),
        "nhwc_dynamic": export(MeanRedNHWC(), root / "c.onnx", (1, 28, 42, 3), {1: "h", 2: "w"}),
        "nhwc_fixed": export(MeanRedNHWC(), root / "d.onnx", (1, 28, 42, 3)),
        "four_channels": export(MeanRed(), root / "e.onnx", (1, 4, 28, 42)),
        "two_inputs": export(TwoInputs(), root / "f.onnx", (1, 3, 28, 42), inputs=2),
        "rank3": export(MeanRed(), root / "g.onnx", (3, 28, 42)),
        "scalar_out": export(WrongOutput(), root / "h.onnx", (1, 3, 28, 42)),
    }


@pytest.fixture()
def rgb():
    img = np.random.default_rng(0).integers(0, 256, (H, W, 3), dtype=np.uint8)
    img[..., 0] = np.linspace(20, 240, W).astype(np.uint8)[None, :]
    return img


def test_input_size_keeps_the_aspect_and_snaps_to_the_multiple():
    assert input_size(480, 640, 518, 14, "short") == (518, 686)  # 640 * 518 / 480 = 690.7 -> 686
    assert input_size(480, 640, 256, 32, "long") == (192, 256)
    assert input_size(60, 80, 518, 14)[0] % 14 == 0
    for h, w in ((45, 70), (480, 640), (1080, 1920), (300, 301)):
        a, b = input_size(h, w, 518, 14)
        assert a % 14 == 0 and b % 14 == 0 and abs(min(a, b) - 518) <= 7
        assert abs((b / a) - (w / h)) / (w / h) < 0.03
    with pytest.raises(ValueError, match="positive"):
        input_size(10, 10, 518, 0)


def test_every_preset_is_complete():
    for name, p in PRESETS.items():
        assert p.name == name and p.layout in ("nchw", "nhwc") and p.fit in ("short", "long")
        assert p.kind in ("metric", "relative", "relative-inverse") and p.multiple >= 1 and p.source
    assert get_preset("depth-anything-v2").multiple == 14
    with pytest.raises(ValueError, match="unknown ONNX preset 'nope'; choose one of depth-anything-v2"):
        get_preset("nope")


def test_preset_feeds_multiples_and_normalises(models, rgb):
    est = OnnxDepthEstimator(models["nchw_dynamic"], preset="depth-anything-v2", scale=1.0)
    assert est.kind == "relative-inverse" and est.layout == "nchw"
    h, w = est.feed_size(H, W)
    assert (h, w) == input_size(H, W, 518, 14) and h % 14 == 0 and w % 14 == 0
    raw = est.raw_output(rgb, CAMERA)
    expected = (rgb[..., 0] / 255.0 - 0.485) / 0.229 + 3.0  # ImageNet-normalised red (+3)
    np.testing.assert_allclose(raw[:, 5:-5], expected[:, 5:-5], atol=0.02)  # resized there and back
    assert "preset depth-anything-v2" in est.describe()
    dpt = OnnxDepthEstimator(models["nchw_dynamic"], preset="midas-dpt", scale=1.0)
    np.testing.assert_allclose(
        dpt.raw_output(rgb, CAMERA)[:, 5:-5], ((rgb[..., 0] / 255.0 - 0.5) / 0.5 + 3.0)[:, 5:-5], atol=0.02
    )
    assert dpt.feed_size(H, W) == (384, 512)


def test_overrides_of_the_preset(models, rgb):
    est = OnnxDepthEstimator(
        models["nchw_dynamic"], preset="depth-anything-v2", kind="metric", mean=(0, 0, 0), std=(1, 1, 1),
        size=58, size_multiple=8,
    )  # fmt: skip
    assert est.feed_size(H, W) == (56, 80)  # 58 -> 56 (nearest multiple of 8), 80 * 58 / 60 = 77.3 -> 80
    np.testing.assert_allclose(
        est.predict(rgb, CAMERA)[:, 5:-5], (rgb[..., 0] / 255.0 + 3.0)[:, 5:-5], atol=0.02
    )
    plain = OnnxDepthEstimator(models["nchw_dynamic"], size_multiple=16)
    assert plain.feed_size(H, W) == (64, 80)  # own size, rounded to the nearest multiple
    with pytest.raises(ValueError, match="three numbers"):
        OnnxDepthEstimator(models["nchw_dynamic"], mean=(0, 0))
    with pytest.raises(ValueError, match="std must be positive"):
        OnnxDepthEstimator(models["nchw_dynamic"], std=(1, 0, 1))


def test_fixed_size_models_are_fed_at_their_size(models, rgb):
    est = OnnxDepthEstimator(models["nchw_fixed"], preset="depth-anything-v2-metric")
    assert est.fixed_hw == (28, 42) and est.feed_size(H, W) == (28, 42) and est.kind == "metric"
    assert est.predict(rgb, CAMERA).shape == (H, W)


@pytest.mark.parametrize("name", ["nhwc_dynamic", "nhwc_fixed"])
def test_nhwc_models(models, rgb, name):
    est = OnnxDepthEstimator(models[name], layout="nhwc")
    auto = OnnxDepthEstimator(models[name])  # channels last read from the shape
    assert est.layout == auto.layout == "nhwc"
    depth = est.predict(rgb, CAMERA)
    assert depth.shape == (H, W) and depth.dtype == np.float32
    expected = (rgb[..., 0] / 255.0 - 0.485) / 0.229 + 3.0
    np.testing.assert_allclose(depth[:, 5:-5], expected[:, 5:-5], atol=0.05 if "fixed" in name else 1e-4)


def test_wrong_layout_is_refused(models):
    with pytest.raises(ValueError, match="is NHWC .* but NCHW was asked for") as info:
        OnnxDepthEstimator(models["nhwc_fixed"], preset="depth-anything-v2", scale=1.0)
    assert "\n" not in str(info.value)
    with pytest.raises(ValueError, match="is NCHW .* but NHWC was asked for"):
        OnnxDepthEstimator(models["nchw_fixed"], layout="nhwc")
    with pytest.raises(ValueError, match="unknown input layout"):
        OnnxDepthEstimator(models["nchw_fixed"], layout="chw")


@pytest.mark.parametrize(
    ("name", "match"),
    [
        ("four_channels", "has 4 channels"),
        ("two_inputs", "must take one input"),
        ("rank3", r"input has shape \[3, 28, 42\]"),
        ("scalar_out", r"output has shape \[1, 1\]; expected a depth map"),
    ],
)
def test_unusable_models_are_refused_at_load(models, name, match):
    with pytest.raises(ValueError, match=match) as info:
        OnnxDepthEstimator(models[name])
    assert "\n" not in str(info.value)


def test_options_through_the_factory(models, rgb):
    opts = DepthModelOptions(
        model=str(models["nchw_dynamic"]), onnx_preset="midas-v21-small", scale=0.5, onnx_multiple=16
    )
    est = depth_estimator(opts)
    assert est is depth_estimator(DepthModelOptions(**{**opts.__dict__}))
    assert est.kind == "relative-inverse" and est.feed_size(480, 640) == (192, 256)
    assert est.predict(rgb, CAMERA).shape == (H, W)
    with pytest.raises(ValueError, match="needs a scale"):
        make_depth_estimator(models["nchw_dynamic"], onnx_preset="depth-anything-v2")
    with pytest.raises(ValueError, match="apply to an .onnx depth model only"):
        make_depth_estimator(None, onnx_size=300)

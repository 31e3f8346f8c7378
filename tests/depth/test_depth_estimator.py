"""Depth estimators behind one interface: the built-in net (tiny random checkpoint) and ONNX models
(tiny torch modules exported in tmp_path), relative-depth alignment and the user-facing errors."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
import torch
from torch import nn

from cuboidcli.camera import Camera
from cuboidcli.depth import BuiltinDepthEstimator, OnnxDepthEstimator, estimate_depth
from cuboidcli.depth.scale import fit_scale_shift
from cuboidcli.factories import make_depth_estimator
from cuboidcli.nets.checkpoint import checkpoint_dict
from cuboidcli.nets.depth import DepthNet, DepthNetConfig, net_from_checkpoint

pytest.importorskip("onnxruntime")

TINY = DepthNetConfig(channels=(4, 8, 8, 8, 8), input_height=32, input_width=48, canonical_focal_px=40.0)
CAMERA = Camera(fx=80.0, fy=80.0, cx=39.5, cy=29.5, width=80, height=60)


pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.fixture()
def rgb() -> np.ndarray:
    """(60, 80, 3) uint8 with a horizontal red ramp (so a model reading red gives a varied output)."""
    img = np.random.default_rng(0).integers(0, 256, (60, 80, 3), dtype=np.uint8)
    img[..., 0] = np.linspace(20, 240, 80).astype(np.uint8)[None, :]
    return img


@pytest.fixture(scope="module")
def tiny_weights(tmp_path_factory):
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("depth") / "depth_tiny.pt"
    torch.save(checkpoint_dict(DepthNet(TINY), {"note": "test"}), path)
    return path


class RedChannel(nn.Module):
    """Output = a * (red in [0, 1]) + b, undoing the ImageNet normalisation: (1, 3, H, W) -> (1, 1, H, W)."""

    def __init__(self, a: float = 4.0, b: float = 1.0) -> None:
        super().__init__()
        self.a, self.b = a, b

    def forward(self, x):
        return (x[:, :1] * 0.229 + 0.485) * self.a + self.b


def export(module: nn.Module, path, height=16, width=24, dynamic=True, channels=3, inputs=1):
    args = tuple(torch.rand(1, channels, height, width) for _ in range(inputs))
    names = [f"in{i}" for i in range(inputs)]
    axes = {n: {2: "h", 3: "w"} for n in names} | {"depth": {2: "h", 3: "w"}} if dynamic else None
    with warnings.catch_warnings():
        warnings.simplefilter("ignore")  # the TorchScript exporter's deprecation notice
        torch.onnx.export(
            module, args, str(path), input_names=names, output_names=["depth"], dynamic_axes=axes,
            opset_version=17, dynamo=False,
        )  # fmt: skip
    return path


@pytest.fixture(scope="module")
def onnx_models(tmp_path_factory):
    root = tmp_path_factory.mktemp("onnx")

    class TwoInputs(nn.Module):
        def forward(self, x, y):
            return x[:, :1] + y[:, :1]

    class TwoChannels(nn.Module):
        def forward(self, x):
            return x[:, :2]

    return {
        "dynamic": export(RedChannel(), root / "dynamic.onnx"),
        "fixed": export(RedChannel(), root / "fixed.onnx", dynamic=False),
        "two_inputs": export(TwoInputs(), root / "two_inputs.onnx", inputs=2),
        "gray_input": export(RedChannel(), root / "gray.onnx", channels=1),
        "two_channel_output": export(TwoChannels(), root / "two_out.onnx"),
    }


def red(rgb: np.ndarray) -> np.ndarray:
    return rgb[..., 0].astype(np.float64) / 255.0


# --- built-in network --------------------------------------------------------------------------------


def test_builtin_shapes_dtype_positive(tiny_weights, rgb):
    est = BuiltinDepthEstimator(tiny_weights)
    depth = est.predict(rgb, CAMERA)
    assert depth.shape == (60, 80) and depth.dtype == np.float32
    assert np.isfinite(depth).all() and (depth > 0).all()
    native = est.predict_native(rgb, CAMERA)
    assert native.shape == (32, 48) and native.dtype == np.float32
    assert "built-in" in est.describe()


def test_builtin_output_range_and_focal_scaling(tiny_weights, rgb):
    """The sigmoid keeps depth inside [min, max] for the canonical camera; a longer lens scales it up."""
    est = BuiltinDepthEstimator(tiny_weights)
    canonical = Camera(fx=40.0 * 80 / 48, fy=40.0 * 60 / 32, cx=39.5, cy=29.5, width=80, height=60)
    assert est.focal_factor(canonical) == pytest.approx(1.0)
    near = est.predict_native(rgb, canonical)
    assert near.min() >= TINY.min_depth_m * 0.999 and near.max() <= TINY.max_depth_m * 1.001
    far = est.predict_native(rgb, Camera(2 * canonical.fx, 2 * canonical.fy, 39.5, 29.5, 80, 60))
    np.testing.assert_allclose(far, 2 * near, rtol=1e-5)


def test_checkpoint_round_trip(tiny_weights):
    ckpt = torch.load(tiny_weights, weights_only=True)
    assert set(ckpt) == {"config", "state_dict", "meta"}
    net = net_from_checkpoint(ckpt)
    assert net.config == TINY and not net.training


def test_builtin_missing_weights(tmp_path, monkeypatch):
    with pytest.raises(FileNotFoundError, match="depth weights .* not found") as info:
        BuiltinDepthEstimator(tmp_path / "nope.pt")
    assert "\n" not in str(info.value)
    with pytest.raises(TypeError, match="weights file or a loaded net"):
        BuiltinDepthEstimator()  # the default weights are the factories' choice (make_depth_estimator)
    monkeypatch.setenv("CUBOIDS_DEPTH_WEIGHTS", str(tmp_path / "missing.pt"))
    with pytest.raises(FileNotFoundError):
        make_depth_estimator()


def test_default_builtin_via_environment(tiny_weights, rgb, monkeypatch):
    monkeypatch.setenv("CUBOIDS_DEPTH_WEIGHTS", str(tiny_weights))
    depth, text = estimate_depth(make_depth_estimator(), rgb, CAMERA)
    assert depth.shape == (60, 80) and "built-in" in text
    with pytest.raises(ValueError, match="metric"):
        make_depth_estimator(kind="relative", scale=2.0)


def test_image_checks(tiny_weights, rgb):
    est = BuiltinDepthEstimator(tiny_weights)
    with pytest.raises(ValueError, match="80x60"):
        est.predict(rgb[:50], CAMERA)
    with pytest.raises(ValueError, match="uint8"):
        est.predict(rgb.astype(np.float32), CAMERA)


# --- ONNX models -------------------------------------------------------------------------------------


def test_onnx_metric_passthrough(onnx_models, rgb):
    depth = OnnxDepthEstimator(onnx_models["dynamic"]).predict(rgb, CAMERA)
    assert depth.shape == (60, 80) and depth.dtype == np.float32
    np.testing.assert_allclose(depth, 4.0 * red(rgb) + 1.0, rtol=1e-5)


def test_onnx_fixed_input_size_is_resized_back(onnx_models):
    flat = np.full((60, 80, 3), 128, dtype=np.uint8)  # constant: resizing changes nothing
    est = OnnxDepthEstimator(onnx_models["fixed"])
    assert est.fixed_hw == (16, 24)
    depth = est.predict(flat, CAMERA)
    assert depth.shape == (60, 80)
    np.testing.assert_allclose(depth, 4.0 * 128 / 255 + 1.0, rtol=1e-5)


def test_relative_alignment_recovers_scale_and_shift(onnx_models, rgb):
    raw = 4.0 * red(rgb) + 1.0  # what the model outputs
    truth = 0.6 * raw + 0.35
    partial = np.zeros_like(truth)
    partial[::7, ::5] = truth[::7, ::5]  # a sparse reference, 0 elsewhere
    est = OnnxDepthEstimator(onnx_models["dynamic"], kind="relative", ref_depth=partial)
    depth = est.predict(rgb, CAMERA)
    np.testing.assert_allclose(depth, truth, rtol=1e-5)
    scale, shift, n = est.alignment
    assert scale == pytest.approx(0.6, rel=1e-5) and shift == pytest.approx(0.35, abs=1e-5)
    assert n == (partial > 0).sum() and "aligned" in est.describe()


def test_relative_inverse_alignment(onnx_models, rgb):
    raw = 4.0 * red(rgb) + 1.0
    truth = 1.0 / (0.3 * raw + 0.05)
    partial = np.where(np.arange(80)[None, :] < 40, truth, np.nan)  # only the left half known
    depth = OnnxDepthEstimator(onnx_models["dynamic"], kind="relative-inverse", ref_depth=partial).predict(
        rgb, CAMERA
    )
    np.testing.assert_allclose(depth, truth, rtol=1e-4)


def test_given_scale_and_shift(onnx_models, rgb):
    est = OnnxDepthEstimator(onnx_models["dynamic"], kind="relative", scale=2.0, shift=-0.5)
    np.testing.assert_allclose(est.predict(rgb, CAMERA), 2.0 * (4.0 * red(rgb) + 1.0) - 0.5, rtol=1e-5)
    assert "scale 2" in est.describe()


def test_depth_with_partial_depth(onnx_models, rgb):
    truth = 0.5 * (4.0 * red(rgb) + 1.0)
    partial = np.where(np.random.default_rng(1).random(truth.shape) < 0.1, truth, 0.0)
    estimator = make_depth_estimator(onnx_models["dynamic"], kind="relative", ref_depth=partial)
    depth, text = estimate_depth(estimator, rgb, CAMERA)
    np.testing.assert_allclose(depth, truth, rtol=1e-4)
    assert "dynamic.onnx" in text and "aligned" in text


@pytest.mark.parametrize(
    ("kwargs", "match"),
    [
        ({"kind": "relative"}, "needs a scale"),
        ({"kind": "metric", "scale": 2.0}, "metric depth model needs no scale"),
        ({"kind": "relative", "scale": 2.0, "ref_depth": np.ones((60, 80))}, "not both"),
        ({"kind": "relative", "shift": 1.0}, "needs a scale"),
        ({"kind": "relative", "scale": -1.0}, "positive"),
        ({"kind": "inverse"}, "unknown depth model kind"),
    ],
)
def test_argument_errors(onnx_models, kwargs, match):
    with pytest.raises(ValueError, match=match):
        OnnxDepthEstimator(onnx_models["dynamic"], **kwargs)


def test_model_shape_errors(onnx_models, rgb, tmp_path):
    with pytest.raises(ValueError, match="one input"):
        OnnxDepthEstimator(onnx_models["two_inputs"])
    with pytest.raises(ValueError, match="1 channels"):
        OnnxDepthEstimator(onnx_models["gray_input"])
    with pytest.raises(ValueError, match="output has shape"):
        OnnxDepthEstimator(onnx_models["two_channel_output"]).predict(rgb, CAMERA)
    with pytest.raises(FileNotFoundError):
        OnnxDepthEstimator(tmp_path / "missing.onnx")
    bad = tmp_path / "bad.onnx"
    bad.write_bytes(b"not a model")
    with pytest.raises(ValueError, match="cannot load ONNX model"):
        OnnxDepthEstimator(bad)
    with pytest.raises(ValueError, match="expected an .onnx file"):
        make_depth_estimator(tmp_path / "model.tflite")


def test_reference_errors(onnx_models, rgb):
    est = OnnxDepthEstimator(onnx_models["dynamic"], kind="relative", ref_depth=np.ones((30, 40)))
    with pytest.raises(ValueError, match="registered"):
        est.predict(rgb, CAMERA)
    raw = np.linspace(1.0, 2.0, 12).reshape(3, 4)
    with pytest.raises(ValueError, match="negative scale.*relative-inverse"):
        fit_scale_shift(raw, 5.0 - raw)
    with pytest.raises(ValueError, match="1 valid pixels"):
        fit_scale_shift(raw, np.where(raw == raw[0, 0], 1.0, 0.0))


# --- training (cuboidcli.learn.depth_train) ----------------------------------------------------------


@pytest.fixture(scope="module")
def tiny_dataset(tmp_path_factory):
    """Ten 64x48 RGB-D frames in the dataset layout: 8 train, 2 val; depth follows the image's red channel."""
    import json

    import cv2

    root = tmp_path_factory.mktemp("rgbd")
    (root / "rgb").mkdir()
    (root / "depth").mkdir()
    rng = np.random.default_rng(0)
    cams, names = {}, []
    for i in range(10):
        name = f"f{i:03d}"
        img = rng.integers(0, 256, (48, 64, 3), dtype=np.uint8)
        depth_mm = (1000 + 12 * img[..., 2].astype(np.float64)).astype(np.uint16)
        depth_mm[:4] = 0  # a band of holes
        cv2.imwrite(str(root / "rgb" / f"{name}.png"), img)
        cv2.imwrite(str(root / "depth" / f"{name}.png"), depth_mm)
        cams[name] = {"fx": 52.0, "fy": 52.0, "cx": 31.5, "cy": 23.5, "width": 64, "height": 48}
        names.append(name)
    (root / "cameras.json").write_text(json.dumps(cams))
    (root / "splits.json").write_text(json.dumps({"train": names[:8], "val": names[8:], "test": []}))
    return root


def test_training_logs_checkpoints_and_resumes_exactly(tiny_dataset, tmp_path):
    from cuboidcli.learn.depth_train import DepthTrainConfig, train_depth

    cfg = DepthTrainConfig(epochs=2, batch=4, warmup=2, log_every=1, min_crop=0.7)
    full = train_depth(tiny_dataset, tmp_path / "full", cfg, TINY)
    assert full["epoch"] == 2 and np.isfinite(full["best_abs_rel"])
    lines = (tmp_path / "full" / "log.jsonl").read_text().splitlines()
    assert sum('"val"' in line for line in lines) == 2
    best = torch.load(tmp_path / "full" / "best.pt", weights_only=True)
    assert set(best) == {"config", "state_dict", "meta"}
    # the canonical focal length: the data's camera resized to the net's 48x32 input, geometric mean
    expected_focal = (52.0 * 48 / 64 * 52.0 * 32 / 48) ** 0.5
    assert best["config"]["canonical_focal_px"] == pytest.approx(expected_focal, rel=1e-9)

    class Stop(Exception):
        pass

    def stop_in_second_epoch(record):
        if record.get("event") == "train" and record["epoch"] == 1:
            raise Stop

    with pytest.raises(Stop):
        train_depth(tiny_dataset, tmp_path / "cut", cfg, TINY, on_event=stop_in_second_epoch)
    resumed = train_depth(tiny_dataset, tmp_path / "cut", cfg, resume=tmp_path / "cut" / "last.pt")
    assert resumed["epoch"] == 2
    a = torch.load(tmp_path / "full" / "last.pt", weights_only=True)["state_dict"]
    b = torch.load(tmp_path / "cut" / "last.pt", weights_only=True)["state_dict"]
    for key in a:
        torch.testing.assert_close(a[key], b[key], rtol=0, atol=0)

"""Depth models a user may hand over that are not what the readers expect: ONNX models whose input is
float16 or float64 (run in their own precision) or not a float at all (refused at load), and
save_pretrained folders without their weights or with some of them missing (refused: transformers would
start those parameters at random). Tiny models built here with onnx.helper and save_pretrained."""

from __future__ import annotations

import shutil

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.factories import make_depth_estimator

onnx = pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")
pytestmark = pytest.mark.usefixtures("one_thread")

H, W = 30, 40
CAMERA = Camera(fx=40.0, fy=40.0, cx=19.5, cy=14.5, width=W, height=H)
FLOATS = {"float16": np.float16, "float32": np.float32, "float64": np.float64}


def tiny_onnx(path, input_type: str, output_type: str | None = None) -> str:
    """A model (1, 3, h, w) -> (1, 1, h, w): the mean of the channels + 3, in ``input_type`` ("float16",
    "float32", "float64", "int64"), its output cast to ``output_type`` (default: the input's)."""
    from onnx import TensorProto, helper, numpy_helper

    elem = {"float16": TensorProto.FLOAT16, "float32": TensorProto.FLOAT, "float64": TensorProto.DOUBLE}
    elem["int64"] = TensorProto.INT64
    output_type = output_type or input_type
    x = helper.make_tensor_value_info("image", elem[input_type], [1, 3, "h", "w"])
    y = helper.make_tensor_value_info("depth", elem[output_type], [1, 1, "h", "w"])
    dtype = FLOATS.get(input_type, np.int64)
    three = numpy_helper.from_array(np.array(3, dtype), "three")
    nodes = [
        helper.make_node("ReduceMean", ["image"], ["mean"], axes=[1], keepdims=1),
        helper.make_node("Add", ["mean", "three"], ["depth" if output_type == input_type else "out"]),
    ]
    if output_type != input_type:
        nodes.append(helper.make_node("Cast", ["out"], ["depth"], to=elem[output_type]))
    graph = helper.make_graph(nodes, "tiny", [x], [y], [three])
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 13)])
    model.ir_version = 8
    onnx.checker.check_model(model)
    onnx.save(model, str(path))
    return str(path)


@pytest.fixture()
def rgb():
    img = np.random.default_rng(0).integers(0, 256, (H, W, 3), dtype=np.uint8)
    img[..., 0] = np.linspace(20, 240, W).astype(np.uint8)[None, :]
    return img


@pytest.mark.parametrize("precision", sorted(FLOATS))
def test_an_onnx_model_of_any_float_precision_runs_in_its_own(tmp_path, rgb, precision):
    est = make_depth_estimator(tiny_onnx(tmp_path / f"{precision}.onnx", precision))
    depth = est.predict(rgb, CAMERA)
    assert depth.dtype == np.float32 and depth.shape == (H, W)
    # (rgb / 255 - ImageNet mean) / std averaged over the channels, + 3: the same map in every precision
    x = (rgb / 255.0 - np.array([0.485, 0.456, 0.406])) / np.array([0.229, 0.224, 0.225])
    np.testing.assert_allclose(depth, x.mean(axis=2) + 3.0, atol=0.02 if precision == "float16" else 1e-4)


@pytest.mark.parametrize(
    ("types", "words"),
    [
        (("int64", None), "the depth model's input is tensor(int64); expected a float tensor"),
        (("float32", "int64"), "the depth model's output is tensor(int64); expected a float tensor"),
    ],
)
def test_an_onnx_model_of_other_types_is_refused_at_load(tmp_path, types, words):
    with pytest.raises(ValueError, match=words.replace("(", r"\(").replace(")", r"\)")) as info:
        make_depth_estimator(tiny_onnx(tmp_path / "m.onnx", *types))
    assert "\n" not in str(info.value)


def test_a_save_pretrained_folder_without_weights_is_refused(hf_models, tmp_path):
    folder = tmp_path / "glpn"
    shutil.copytree(hf_models["glpn"], folder)
    for weights in folder.glob("*.safetensors"):
        weights.unlink()
    with pytest.raises(ValueError, match="has a config.json but no weights") as info:
        make_depth_estimator(folder)
    assert "\n" not in str(info.value) and "save_pretrained" in str(info.value)


def test_weights_that_lack_parameters_are_refused_not_started_at_random(hf_models, tmp_path):
    import logging

    from safetensors.torch import load_file, save_file

    folder = tmp_path / "glpn"
    shutil.copytree(hf_models["glpn"], folder)
    weights = folder / "model.safetensors"
    state = load_file(weights)
    dropped = sorted(state)[-1]
    save_file({k: v for k, v in state.items() if k != dropped}, weights, metadata={"format": "pt"})
    reports: list[str] = []
    listener = logging.Handler()
    listener.emit = lambda record: reports.append(record.getMessage())
    logging.getLogger("transformers").addHandler(listener)
    try:
        with pytest.raises(ValueError, match="its weights lack 1 of the model's parameters") as info:
            make_depth_estimator(folder)
    finally:
        logging.getLogger("transformers").removeHandler(listener)
    assert dropped in str(info.value) and "\n" not in str(info.value)
    assert not any("MISSING" in r for r in reports)  # transformers' own table of them stays out

"""Edges of cuboidcli.depth.onnx: every output layout it accepts gives the same depth map, the declared
output shapes it refuses at load, the layout read from the input's shape, and the size options' bounds.
Tiny models built with onnx.helper in a tmp folder."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.depth import OnnxDepthEstimator

onnx = pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")
pytestmark = pytest.mark.usefixtures("one_thread")

H, W = 12, 18
CAMERA = Camera(fx=20.0, fy=20.0, cx=8.5, cy=5.5, width=W, height=H)


def red_model(path, out_shape, in_shape=(1, 3, 4, 6), nhwc: bool = False) -> str:
    """A model whose output is its input's red channel + 3 (input ``in_shape``, NCHW or NHWC; str entries
    are dynamic) reshaped to ``out_shape`` (a 0 there copies the input's axis)."""
    from onnx import TensorProto, helper, numpy_helper

    x = helper.make_tensor_value_info("image", TensorProto.FLOAT, list(in_shape))
    # onnxruntime reads the output's shape from the graph (shape inference), not from this declaration
    y = helper.make_tensor_value_info("depth", TensorProto.FLOAT, None)
    axis = 3 if nhwc else 1
    inits = [
        numpy_helper.from_array(np.array(3, np.float32), "three"),
        numpy_helper.from_array(np.array([0], np.int64), "start"),
        numpy_helper.from_array(np.array([1], np.int64), "end"),
        numpy_helper.from_array(np.array([axis], np.int64), "axis"),
        numpy_helper.from_array(np.array(out_shape, np.int64), "shape"),
    ]
    nodes = [
        helper.make_node("Slice", ["image", "start", "end", "axis"], ["red"]),
        helper.make_node("Add", ["red", "three"], ["plus"]),
    ]
    if nhwc:  # (1, h, w, 1) -> (1, 1, h, w) so that the reshape below reads the same order as NCHW
        nodes.append(helper.make_node("Transpose", ["plus"], ["nchw"], perm=[0, 3, 1, 2]))
    nodes.append(helper.make_node("Reshape", ["nchw" if nhwc else "plus", "shape"], ["depth"]))
    graph = helper.make_graph(nodes, "red", [x], [y], inits)
    model = helper.make_model(graph, opset_imports=[helper.make_opsetid("", 14)])
    model.ir_version = 8
    onnx.save(model, str(path))
    return str(path)


@pytest.fixture()
def rgb():
    img = np.random.default_rng(1).integers(0, 256, (H, W, 3), dtype=np.uint8)
    img[..., 0] = np.linspace(10, 250, W).astype(np.uint8)[None, :] // 2 + np.arange(H)[:, None] * 10
    return img


@pytest.mark.parametrize(
    "shape, plain",
    [((1, 4, 6), (1, 1, 4, 6)), ((1, 4, 6, 1), (1, 1, 4, 6)), ((4, 6), (1, 1, 4, 6)), ((1, 1, 4, 6), (4, 6))]
    + [((1, 2, 12, 1), (2, 12))],  # two rows, channels last
)
def test_every_accepted_output_layout_gives_the_same_map(tmp_path, rgb, shape, plain):
    ref = OnnxDepthEstimator(red_model(tmp_path / "ref.onnx", plain), mean=(0, 0, 0), std=(1, 1, 1))
    est = OnnxDepthEstimator(red_model(tmp_path / "m.onnx", shape), mean=(0, 0, 0), std=(1, 1, 1))
    expected = ref.raw_output(rgb, CAMERA)
    assert expected.shape == (H, W) and expected.min() > 3.0 and np.ptp(expected) > 0.5
    np.testing.assert_array_equal(est.raw_output(rgb, CAMERA), expected)


@pytest.mark.parametrize("shape, axis", [((1, 1, 1, 24), 0), ((1, 24, 1, 1), 1)])
def test_a_one_row_or_one_column_output_is_stretched_over_the_image(tmp_path, rgb, shape, axis):
    # (1, 1, 1, w): a map one row high, (1, h, 1, 1): one column wide; only the leading ones go
    model = red_model(tmp_path / "line.onnx", shape)
    raw = OnnxDepthEstimator(model, mean=(0, 0, 0), std=(1, 1, 1)).raw_output(rgb, CAMERA)
    assert raw.shape == (H, W) and np.ptp(raw) > 0.1
    line = raw[:1] if axis == 0 else raw[:, :1]
    np.testing.assert_allclose(raw, np.broadcast_to(line, (H, W)))  # the same in every row / column


DYNAMIC_BATCH = ("n", 3, 4, 6)


@pytest.mark.parametrize(
    "in_shape, out_shape",
    [
        ((1, 3, 4, 6), (2, 12)),  # (h, w), two rows
        (DYNAMIC_BATCH, (0, 1, 4, 6)),  # 0: the input's (dynamic) batch
        (DYNAMIC_BATCH, (0, 4, 6, 1)),
        (DYNAMIC_BATCH, (0, 4, 6)),
        ((1, 3, 4, 6), (1, 2, 12, 1)),  # (1, h, w, 1)
    ],
)
def test_output_shapes_that_are_depth_maps_load(tmp_path, in_shape, out_shape):
    OnnxDepthEstimator(red_model(tmp_path / "m.onnx", out_shape, in_shape=in_shape))


@pytest.mark.parametrize(
    "in_shape, out_shape",
    [
        ((1, 3, 4, 6), (1, 24)),  # (1, w): no rows
        ((1, 3, 4, 6), (24,)),
        ((1, 3, 4, 6), (1, 1, 1, 4, 6)),  # rank 5
        ((1, 3, 4, 6), (2, 2, 6)),  # a batch of 2
        ((1, 3, 4, 6), (2, 1, 2, 6)),
        ((1, 3, 4, 6), (1, 2, 2, 6)),  # 2 channels
        ((1, 3, 4, 6), (1, 4, 3, 2)),  # channels last, 2 of them
        ((1, 3, 4, 6), (1, 2, 3, 2)),
        ((1, 3, 4, 6), (1, 2, 1, 12)),  # 2 channels of one row
        ((1, 3, 0, 6), (1, 1, 0, 6)),  # empty
    ],
)
def test_output_shapes_that_are_not_depth_maps_are_refused_at_load(tmp_path, in_shape, out_shape):
    with pytest.raises(ValueError, match="output has shape"):
        OnnxDepthEstimator(red_model(tmp_path / "m.onnx", out_shape, in_shape=in_shape))


def test_layout_is_read_from_the_input_shape(tmp_path, rgb):
    nhwc = red_model(tmp_path / "nhwc.onnx", (1, 1, 4, 6), in_shape=(1, 4, 6, 3), nhwc=True)
    est = OnnxDepthEstimator(nhwc, mean=(0, 0, 0), std=(1, 1, 1))
    assert est.layout == "nhwc" and est.fixed_hw == (4, 6)
    nchw = OnnxDepthEstimator(red_model(tmp_path / "nchw.onnx", (1, 1, 4, 6)), mean=(0, 0, 0), std=(1, 1, 1))
    np.testing.assert_array_equal(est.raw_output(rgb, CAMERA), nchw.raw_output(rgb, CAMERA))
    # a 4-channel NCHW input forced to NHWC: neither layout reads 3 channels; the count is reported
    four = red_model(tmp_path / "four.onnx", (1, 1, 4, 6), in_shape=(1, 4, 4, 6))
    with pytest.raises(ValueError, match=r"has 6 channels .*NHWC\); expected 3"):
        OnnxDepthEstimator(four, layout="nhwc")


def test_size_options_bounds(tmp_path):
    dynamic = red_model(tmp_path / "dyn.onnx", (1, 1, 4, 6), in_shape=(1, 3, "h", "w"))
    assert OnnxDepthEstimator(dynamic).feed_size(31, 41) == (31, 41)  # own size: multiple 1
    assert OnnxDepthEstimator(dynamic, size=1).feed_size(31, 41) == (1, 1)
    for bad in ({"size_multiple": 0}, {"size": 0}, {"size": -5, "size_multiple": 2}):
        with pytest.raises(ValueError, match="must be positive"):
            OnnxDepthEstimator(dynamic, **bad)
    with pytest.raises(ValueError, match="three numbers"):
        OnnxDepthEstimator(dynamic, mean=(0.5, float("nan"), 0.5))


def test_a_partly_dynamic_input_is_fed_at_the_image_size(tmp_path):
    # fixed height 4, dynamic width: not a fixed-size model, so the image goes in at its own size
    model = red_model(tmp_path / "partly.onnx", (1, 1, 4, 0), in_shape=(1, 3, 4, "w"))
    est = OnnxDepthEstimator(model, mean=(0, 0, 0), std=(1, 1, 1))
    assert est.fixed_hw is None
    rgb = np.full((4, 7, 3), 51, np.uint8)
    raw = est.raw_output(rgb, Camera(fx=5.0, fy=5.0, cx=3.0, cy=1.5, width=7, height=4))
    np.testing.assert_allclose(raw, np.full((4, 7), 3.2), rtol=1e-6)  # 51 / 255 + 3

"""Named input/output conventions of common monocular-depth ONNX exports (``--onnx-preset NAME``).

An ONNX file does not say how its input is normalised or what its output means; a preset writes that down
for one family of exports. Each preset below cites where its convention comes from (docs/depth_models.md
has the same table for users). Only conventions that could be pinned to a source are here: Metric3D and
UniDepth exports are left out (their ONNX files need the camera's focal length or intrinsics as an input
or a rescale that depends on their canonical camera, which an RGB-only preset cannot express).
"""

from __future__ import annotations

from dataclasses import dataclass

IMAGENET = ((0.485, 0.456, 0.406), (0.229, 0.224, 0.225))
HALF = ((0.5, 0.5, 0.5), (0.5, 0.5, 0.5))


@dataclass(frozen=True)
class OnnxPreset:
    """How to feed an ONNX depth export and read its output."""

    name: str
    layout: str
    """"nchw" (1, 3, H, W) or "nhwc" (1, H, W, 3); RGB channel order, float32."""
    mean: tuple[float, float, float]
    std: tuple[float, float, float]
    """Per-channel normalisation of the [0, 1] image: (rgb / 255 - mean) / std."""
    size: int
    """Input size for models with dynamic spatial axes: the side named by ``fit`` is resized to ``size``
    (aspect kept), then both sides are rounded to multiples of ``multiple``. Fixed-size models are fed at
    their own size."""
    multiple: int
    fit: str
    """"short": the shorter side becomes ``size`` (Depth Anything's lower bound); "long": the longer side
    does (MiDaS's upper bound)."""
    kind: str
    """metric | relative | relative-inverse (as :data:`cuboidcli.depth.scale.KINDS`)."""
    source: str
    """Where the convention is written down."""


_DA_SOURCE = (
    "Depth Anything V2 (github.com/DepthAnything/Depth-Anything-V2, DINOv2 patch 14, 518 px) as exported by "
    "github.com/fabio-sim/Depth-Anything-ONNX (dynamo.py: RGB / 255, ImageNet mean/std, NCHW, "
    "sides multiples "
    "of 14, default 518)"
)

PRESETS: dict[str, OnnxPreset] = {
    p.name: p
    for p in (
        OnnxPreset(
            "depth-anything-v2", "nchw", *IMAGENET, 518, 14, "short", "relative-inverse",
            _DA_SOURCE + "; relative models predict affine-invariant inverse depth (disparity)",
        ),
        OnnxPreset(
            "depth-anything-v2-metric", "nchw", *IMAGENET, 518, 14, "short", "metric",
            _DA_SOURCE + "; the metric_depth models (Hypersim indoor, max 20 m; Virtual KITTI outdoor, "
            "max 80 m) predict depth in metres",
        ),
        OnnxPreset(
            "midas-v21-small", "nchw", *IMAGENET, 256, 32, "long", "relative-inverse",
            "MiDaS v2.1 small (github.com/isl-org/MiDaS hubconf.py small_transform: 256 px upper bound, "
            "multiple of 32, ImageNet mean/std); relative inverse depth",
        ),
        OnnxPreset(
            "midas-v21", "nchw", *IMAGENET, 384, 32, "long", "relative-inverse",
            "MiDaS v2.1 (github.com/isl-org/MiDaS hubconf.py default_transform: 384 px upper bound, multiple "
            "of 32, ImageNet mean/std); relative inverse depth",
        ),
        OnnxPreset(
            "midas-dpt", "nchw", *HALF, 384, 32, "short", "relative-inverse",
            "MiDaS v3 DPT_Large / DPT_Hybrid (github.com/isl-org/MiDaS hubconf.py dpt_transform: 384 px, "
            "'minimal' resize, multiple of 32, mean 0.5 std 0.5); relative inverse depth",
        ),
    )
}  # fmt: skip


def get_preset(name: str) -> OnnxPreset:
    """The preset ``name``; a one-line ValueError listing the known names otherwise."""
    try:
        return PRESETS[name]
    except KeyError:
        raise ValueError(f"unknown ONNX preset {name!r}; choose one of {', '.join(PRESETS)}") from None


def input_size(height: int, width: int, size: int, multiple: int, fit: str = "short") -> tuple[int, int]:
    """(h, w) to feed an image of ``height`` x ``width`` to a model with dynamic spatial axes: the ``fit``
    side ("short" or "long") resized to ``size`` with the aspect kept, both sides rounded to the nearest
    positive multiple of ``multiple``."""
    if size <= 0 or multiple <= 0:
        raise ValueError(f"the input size and its multiple must be positive, got {size} and {multiple}")
    ref = min(height, width) if fit == "short" else max(height, width)
    f = size / ref

    def snap(x: float) -> int:
        return max(multiple, int(round(x * f / multiple)) * multiple)

    return snap(height), snap(width)

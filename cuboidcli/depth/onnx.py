"""A user's monocular depth network exported to ONNX, run with onnxruntime (:class:`OnnxDepthEstimator`).

Expected tensors:

- input: one tensor ``(1, 3, h, w)`` (NCHW) or ``(1, h, w, 3)`` (NHWC) float32 (or float16 or float64:
  the image is fed in the model's precision), RGB order,
  ``(rgb / 255 - mean) / std`` per channel (``mean``/``std`` default to the ImageNet statistics; pass
  (0, 0, 0) and (1, 1, 1) for plain [0, 1]). ``h, w`` fixed in the model: the image is resized to them
  and the output resized back; dynamic: the image is fed at the preset's size (sides multiples of its
  ``multiple``), at ``input_size``, or at its own size. A named preset
  (:mod:`cuboidcli.depth.onnx_presets`) sets layout, normalisation, size and kind for common exports.
- output: the first output, ``(1, 1, h', w')``, ``(1, h', w')``, ``(1, h', w', 1)`` or ``(h', w')``
  float (any precision), resized bilinearly to the image size if different. ``kind`` says what it
  holds: ``metric`` depth in metres; ``relative`` depth up to an unknown scale and shift
  (d = scale * r + shift, m); ``relative-inverse`` inverse depth up to scale and shift
  (1 / d = scale * r + shift, 1/m; MiDaS / Depth Anything style). Relative outputs are scaled by
  :class:`cuboidcli.depth.scale.DepthScaling`: a given scale (and shift), a least-squares fit to a
  partial reference depth map over the reference's valid pixels, or the camera's height above the floor.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.depth.image import check_rgb, resize
from cuboidcli.depth.scale import DepthScaling
from cuboidcli.nets.depth import IMAGENET_MEAN, IMAGENET_STD

#: The input and output types of a depth model that are read, with the numpy type its input is fed as.
FLOAT_TENSORS = {"tensor(float)": np.float32, "tensor(float16)": np.float16, "tensor(double)": np.float64}


def _normalised_nchw(rgb: np.ndarray, mean, std) -> np.ndarray:
    """uint8 (h, w, 3) -> float32 (1, 3, h, w), (rgb / 255 - mean) / std."""
    x = rgb.astype(np.float32) / 255.0
    x = (x - np.asarray(mean, np.float32)) / np.asarray(std, np.float32)
    return np.ascontiguousarray(x.transpose(2, 0, 1)[None])


class OnnxDepthEstimator:
    """A user's monocular depth network in ONNX (tensor layout in the module docstring).

    ``kind``: metric | relative | relative-inverse (None: the preset's, else metric). Relative outputs
    need ``scale`` (and optionally ``shift``, default 0), ``ref_depth`` or ``camera_height_m``
    (:class:`DepthScaling`). ``preset``: a named convention (:mod:`cuboidcli.depth.onnx_presets`) that sets
    the layout, normalisation, input size and kind; ``layout`` ("nchw" | "nhwc"; None: the preset's, else
    read from the model's input shape), ``mean``/``std``, ``size``/``size_multiple`` (dynamic spatial axes:
    the shorter side (the preset's side) resized to ``size``, both sides rounded to multiples of
    ``size_multiple``) override it. ``input_size``: an explicit (h, w) for a model with dynamic spatial axes.
    Without a preset or size a dynamic model is fed at the image's own size (rounded to ``size_multiple``).
    Depth that comes out non-positive or non-finite after alignment is reported as 0 (unknown).
    """

    predicts_focal = False

    def __init__(
        self,
        path: str | os.PathLike,
        kind: str | None = None,
        scale: float | None = None,
        shift: float | None = None,
        ref_depth: np.ndarray | None = None,
        mean=None,
        std=None,
        input_size: tuple[int, int] | None = None,
        *,
        preset: str | None = None,
        layout: str | None = None,
        size: int | None = None,
        size_multiple: int | None = None,
        camera_height_m: float | None = None,
    ) -> None:
        from cuboidcli.depth.onnx_presets import get_preset

        self.preset = get_preset(preset) if preset is not None else None
        p = self.preset
        kind = kind or (p.kind if p else "metric")
        self.scaling = DepthScaling(kind, scale, shift, ref_depth, camera_height_m)
        if layout is not None and layout not in ("nchw", "nhwc"):
            raise ValueError(f"unknown input layout {layout!r}; choose nchw or nhwc")
        self.path = Path(path)
        if not self.path.is_file():
            raise FileNotFoundError(f"depth model {self.path} not found")
        try:
            import onnxruntime as ort  # optional dependency: imported only when an ONNX model is used
        except ImportError as e:
            raise ImportError(
                "running an ONNX depth model needs onnxruntime (a dependency of cuboids): "
                "pip install onnxruntime"
            ) from e
        self.mean = tuple(mean) if mean is not None else (p.mean if p else IMAGENET_MEAN)
        self.std = tuple(std) if std is not None else (p.std if p else IMAGENET_STD)
        for name, v in (("mean", self.mean), ("std", self.std)):
            if len(v) != 3 or not all(math.isfinite(x) for x in v):
                raise ValueError(f"the input {name} must be three numbers, got {v}")
        if not all(x > 0 for x in self.std):
            raise ValueError(f"the input std must be positive, got {self.std}")
        self.size = size if size is not None else (p.size if p else None)
        self.size_multiple = size_multiple if size_multiple is not None else (p.multiple if p else 1)
        if self.size_multiple < 1 or (self.size is not None and self.size < 1):
            raise ValueError(
                f"the input size and multiple must be positive, got {self.size}, {self.size_multiple}"
            )
        self.fit = p.fit if p else "short"
        self.input_size = input_size
        try:
            self.session = ort.InferenceSession(str(self.path), providers=["CPUExecutionProvider"])
        except Exception as e:  # onnxruntime raises its own exception types for unreadable models
            raise ValueError(f"cannot load ONNX model {self.path}: {str(e).splitlines()[0]}") from e
        self.layout = layout or (p.layout if p else None)
        self.input_name, self.fixed_hw = self._inspect_input()
        self._inspect_output()

    # the scaling's kind and last alignment, read on the estimator like every estimator's kind
    @property
    def kind(self) -> str:
        return self.scaling.kind

    @property
    def alignment(self) -> tuple[float, float, int] | None:
        return self.scaling.alignment

    def _inspect_input(self) -> tuple[str, tuple[int, int] | None]:
        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            names = ", ".join(i.name for i in inputs)
            raise ValueError(
                f"the depth model must take one input (an RGB image), it takes {len(inputs)}: {names}"
            )
        shape = list(inputs[0].shape)
        if len(shape) != 4:
            raise ValueError(
                f"the depth model's input has shape {shape}; expected (1, 3, H, W) or (1, H, W, 3)"
            )
        if inputs[0].type not in FLOAT_TENSORS:
            raise ValueError(
                f"the depth model's input is {inputs[0].type}; expected a float tensor "
                f"({', '.join(FLOAT_TENSORS)})"
            )
        # the image is fed in the model's own precision: onnxruntime converts nothing
        self.input_dtype = FLOAT_TENSORS[inputs[0].type]
        n = shape[0]
        first, last = shape[1], shape[3]
        if self.layout is None:  # read it from the shape: channels of 3 first or last
            self.layout = "nhwc" if (last == 3 and first != 3) else "nchw"
        c, h, w = (first, shape[2], last) if self.layout == "nchw" else (last, shape[1], shape[2])
        if isinstance(c, int) and c != 3:
            if self.layout == "nchw" and last == 3:
                raise ValueError(
                    f"the depth model's input {shape} is NHWC (channels last) but NCHW was asked for "
                    "(by the preset or the layout option); use layout nhwc"
                )
            if self.layout == "nhwc" and first == 3:
                raise ValueError(
                    f"the depth model's input {shape} is NCHW (channels first) but NHWC was asked for "
                    "(by the preset or the layout option); use layout nchw"
                )
            raise ValueError(
                f"the depth model's input has {c} channels ({shape}, {self.layout.upper()}); expected 3 (RGB)"
            )
        if isinstance(n, int) and n != 1:
            raise ValueError(f"the depth model's input has a fixed batch of {n}; expected 1 or dynamic")
        fixed = (h, w) if isinstance(h, int) and isinstance(w, int) else None
        return inputs[0].name, fixed

    def _inspect_output(self) -> None:
        """Refuse a first output whose declared type or shape cannot be a depth map (one line)."""
        output = self.session.get_outputs()[0]
        if output.type not in FLOAT_TENSORS:
            raise ValueError(
                f"the depth model's output is {output.type}; expected a float tensor "
                f"({', '.join(FLOAT_TENSORS)})"
            )
        shape = list(output.shape)
        fixed = [d for d in shape if isinstance(d, int)]
        ok = 2 <= len(shape) <= 4
        if ok and len(shape) >= 3:
            # (1, h, w), (1, 1, h, w) or (1, h, w, 1): every leading/trailing extra axis is 1 (or dynamic)
            extra = [shape[0]] + ([shape[1]] if len(shape) == 4 and shape[-1] != 1 else [])
            if len(shape) == 4 and shape[-1] == 1:
                extra = [shape[0]]
            ok = all(not isinstance(d, int) or d == 1 for d in extra)
        if ok and len(shape) == 2:
            ok = all(not isinstance(d, int) or d > 1 for d in shape)
        if not ok or any(d == 0 for d in fixed):
            raise ValueError(
                f"the depth model's output has shape {shape}; expected a depth map (1, 1, H, W), (1, H, W), "
                "(1, H, W, 1) or (H, W)"
            )

    def feed_size(self, height: int, width: int) -> tuple[int, int]:
        """(h, w) the image of ``height`` x ``width`` is resized to before it is fed to the model."""
        from cuboidcli.depth.onnx_presets import input_size

        if self.fixed_hw is not None:
            return self.fixed_hw
        if self.input_size is not None:
            return self.input_size
        if self.size is not None:
            return input_size(height, width, self.size, self.size_multiple, self.fit)
        m = self.size_multiple
        return max(m, round(height / m) * m), max(m, round(width / m) * m)

    def raw_output(self, rgb: np.ndarray, camera: Camera) -> np.ndarray:
        """The model's output (before alignment), resized to the image: float64 (H, W)."""
        check_rgb(rgb, camera)
        h, w = self.feed_size(*rgb.shape[:2])
        x = _normalised_nchw(resize(rgb, h, w), self.mean, self.std)
        if self.layout == "nhwc":
            x = np.ascontiguousarray(x.transpose(0, 2, 3, 1))
        x = x.astype(self.input_dtype, copy=False)
        try:
            out = self.session.run(None, {self.input_name: x})[0]
        except Exception as e:  # a model that rejects the size raises an onnxruntime error
            raise ValueError(f"the depth model failed on a {w}x{h} input: {str(e).splitlines()[0]}") from e
        out = np.asarray(out)
        if out.ndim == 4 and out.shape[-1] == 1 and out.shape[1] != 1:
            out = out[..., 0]  # (1, h, w, 1)
        while out.ndim > 2 and out.shape[0] == 1:
            out = out[0]
        if out.ndim != 2:
            raise ValueError(
                f"the depth model's output has shape {out.shape}; expected (1, 1, H, W), (1, H, W) or (H, W)"
            )
        return resize(out.astype(np.float32), camera.height, camera.width).astype(np.float64)

    def predict(self, rgb: np.ndarray, camera: Camera) -> np.ndarray:
        """Metric depth at the image's resolution, float32 (H, W), metres; 0 where unknown."""
        return self.scaling.to_metres(self.raw_output(rgb, camera), camera)

    def describe(self) -> str:
        preset = f", preset {self.preset.name}" if self.preset is not None else ""
        return f"depth estimated from RGB by {self.path.name} ({self.scaling.describe()}{preset})"

"""Depth estimators f_v (paper Sec. 3): an RGB image in, a metric depth map for the fitting pipeline out.

Every estimator implements :class:`DepthEstimator`: ``predict(rgb, camera)`` with ``rgb`` an ``(H, W, 3)``
uint8 RGB image and ``camera`` its intrinsics (``camera.width x camera.height == W x H``) returns depth in
metres, float32 ``(H, W)`` at the image's full resolution; 0 marks pixels without a usable estimate. The
fitting pipeline subsamples this map to its fitting grid (every 8th pixel) itself.

- :class:`BuiltinDepthEstimator`: the project's own network (:mod:`cuboidcli.nets.depth`), from a weights
  file or a loaded net (the default file, ``models/depth_v4.pt``, is the weights registry's:
  :func:`cuboidcli.factories.make_depth_estimator` builds an estimator for a ``--depth-model`` value).
- :class:`OnnxDepthEstimator`: a user's monocular network exported to ONNX. Expected tensors:

  * input: one tensor ``(1, 3, h, w)`` (NCHW) or ``(1, h, w, 3)`` (NHWC) float32, RGB order,
    ``(rgb / 255 - mean) / std`` per channel (``mean``/``std`` default to the ImageNet statistics; pass
    (0, 0, 0) and (1, 1, 1) for plain [0, 1]). ``h, w`` fixed in the model: the image is resized to them
    and the output resized back; dynamic: the image is fed at the preset's size (sides multiples of its
    ``multiple``), at ``input_size``, or at its own size. A named preset
    (:mod:`cuboidcli.depth.onnx_presets`) sets layout, normalisation, size and kind for common exports.
  * output: the first output, ``(1, 1, h', w')``, ``(1, h', w')``, ``(1, h', w', 1)`` or ``(h', w')``
    float32, resized bilinearly to the image size if different. ``kind`` says what it holds: ``metric``
    depth in metres; ``relative`` depth up to an unknown scale and shift (d = scale * r + shift, m);
    ``relative-inverse`` inverse depth up to scale and shift (1 / d = scale * r + shift, 1/m; MiDaS /
    Depth Anything style). Relative outputs are scaled by :class:`DepthScaling`: a given scale (and
    shift), a least-squares fit to a partial reference depth map over the reference's valid pixels, or
    the camera's height above the floor (:mod:`cuboidcli.depth.scale`).
- :class:`cuboidcli.depth.hf.HFDepthEstimator`: a Hugging Face ``transformers`` depth-estimation model
  (Depth Anything, DPT, ZoeDepth, GLPN, Depth Pro), from a ``save_pretrained`` folder or ``hf:owner/name``.
"""

from __future__ import annotations

import math
import os
import time
from pathlib import Path
from typing import Protocol

import numpy as np
import torch

from cuboidcli.camera import Camera
from cuboidcli.nets.depth import IMAGENET_MEAN, IMAGENET_STD, DepthNet, net_from_checkpoint

KINDS = ("metric", "relative", "relative-inverse")


class DepthEstimator(Protocol):
    """Monocular depth: ``predict(rgb (H, W, 3) uint8, camera) -> depth_m (H, W) float32``, 0 = unknown.

    ``predicts_focal``: True for an estimator that also predicts the focal length when the camera is not
    known; it then has ``predict_with_focal(rgb) -> (depth_m (H, W) float32, focal_px)`` (focal length in
    pixels of the full-resolution image, principal point at the image centre).
    """

    predicts_focal: bool

    def predict(self, rgb: np.ndarray, camera: Camera) -> np.ndarray: ...

    def describe(self) -> str:
        """One line for the user: which model produced the depth and how it was scaled."""
        ...


def check_rgb(rgb: np.ndarray, camera: Camera) -> None:
    """Raise a one-line ValueError unless ``rgb`` is (H, W, 3) uint8 of the camera's size."""
    if not isinstance(rgb, np.ndarray) or rgb.ndim != 3 or rgb.shape[2] != 3 or rgb.dtype != np.uint8:
        desc = f"{rgb.dtype} {rgb.shape}" if isinstance(rgb, np.ndarray) else type(rgb).__name__
        raise ValueError(f"expected an RGB image as uint8 (H, W, 3), got {desc}")
    if rgb.shape[:2] != (camera.height, camera.width):
        raise ValueError(
            f"the image is {rgb.shape[1]}x{rgb.shape[0]} but the intrinsics are for "
            f"{camera.width}x{camera.height}"
        )


def resize(img: np.ndarray, height: int, width: int) -> np.ndarray:
    """Resize an image or map to (height, width): area averaging when shrinking, bilinear otherwise."""
    import cv2

    if img.shape[:2] == (height, width):
        return img
    shrink = height < img.shape[0] and width < img.shape[1]
    return cv2.resize(img, (width, height), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_LINEAR)


def _normalised_nchw(rgb: np.ndarray, mean, std) -> np.ndarray:
    """uint8 (h, w, 3) -> float32 (1, 3, h, w), (rgb / 255 - mean) / std."""
    x = rgb.astype(np.float32) / 255.0
    x = (x - np.asarray(mean, np.float32)) / np.asarray(std, np.float32)
    return np.ascontiguousarray(x.transpose(2, 0, 1)[None])


def focal_factor(config, camera: Camera) -> float:
    """f / f_canonical for a depth net of ``config`` (a DepthNetConfig) seeing ``camera``'s image resized to
    its input size: the factor that turns its canonical-camera prediction into this camera's metric depth."""
    fx = camera.fx * config.input_width / camera.width
    fy = camera.fy * config.input_height / camera.height
    return math.sqrt(fx * fy) / config.canonical_focal_px


class BuiltinDepthEstimator:
    """The built-in network: metric depth for any camera.

    The image is resized to the net's input size; the net predicts depth for its canonical camera, and
    the prediction is multiplied by f / f_canonical, f being the geometric mean of the resized image's
    focal lengths: an object of a given apparent size lies proportionally farther from a camera with a
    longer lens. The map is then resized back to the full image.
    """

    predicts_focal = False
    """Only estimators that predict the camera's focal length (Depth Pro) have ``predict_with_focal``."""

    def __init__(
        self,
        weights: str | os.PathLike | None = None,
        device: str | torch.device = "cpu",
        net: DepthNet | None = None,
    ) -> None:
        if net is None and weights is None:
            raise TypeError("BuiltinDepthEstimator needs a weights file or a loaded net")
        self.device = torch.device(device)
        self.path = None
        if net is None:
            self.path = Path(weights)
            if not self.path.is_file():
                raise FileNotFoundError(
                    f"depth weights {self.path} not found; pass a .pt file written by the depth trainer "
                    "or an ONNX model with --depth-model"
                )
            from cuboidcli.io.checkpoints import load_net

            net = load_net(self.path, "depth", net_from_checkpoint)
        self.net = net.to(self.device).eval()

    def focal_factor(self, camera: Camera) -> float:
        """f / f_canonical of the camera after resizing to the net's input size."""
        return focal_factor(self.net.config, camera)

    def predict_native(self, rgb: np.ndarray, camera: Camera) -> np.ndarray:
        """Metric depth at the net's input resolution, float32 (input_height, input_width)."""
        check_rgb(rgb, camera)
        cfg = self.net.config
        x = torch.from_numpy(resize(rgb, cfg.input_height, cfg.input_width)).to(self.device)
        x = x.permute(2, 0, 1)[None].float() / 255.0
        with torch.inference_mode():
            depth = self.net(self.net.normalise(x))[0, 0]
        return (depth.float().cpu().numpy() * self.focal_factor(camera)).astype(np.float32)

    def predict(self, rgb: np.ndarray, camera: Camera) -> np.ndarray:
        """Metric depth at the image's resolution, float32 (H, W), metres."""
        return resize(self.predict_native(rgb, camera), camera.height, camera.width).astype(np.float32)

    def describe(self) -> str:
        where = self.path.name if self.path is not None else "in-memory weights"
        return f"depth estimated from RGB by the built-in network ({where}, metric)"


class DepthScaling:
    """How a model's raw output becomes metres: ``kind`` (metric | relative | relative-inverse) and, for
    relative kinds, exactly one source of scale: ``scale`` (and ``shift``, default 0), ``ref_depth`` (a
    partial depth map (H, W) in metres, 0/NaN where unknown, to which scale and shift are fitted by least
    squares) or ``camera_height_m`` (the camera's height above the floor: the output is taken with shift 0
    and scaled so that the floor lies that far below the camera, :mod:`cuboidcli.depth.scale`).

    Built before any network is loaded, so that a wrong combination fails at once (one-line ValueError).
    """

    def __init__(
        self,
        kind: str = "metric",
        scale: float | None = None,
        shift: float | None = None,
        ref_depth: np.ndarray | None = None,
        camera_height_m: float | None = None,
    ) -> None:
        check_alignment_args(kind, scale, shift, ref_depth, camera_height_m)
        self.kind, self.scale, self.shift, self.ref_depth = kind, scale, shift, ref_depth
        self.camera_height_m = camera_height_m
        self.alignment: tuple[float, float, int] | None = None
        """(scale, shift, pixels) of the last least-squares fit to ``ref_depth``."""
        self.floor = None
        """The last :class:`cuboidcli.depth.scale.FloorScale` for ``camera_height_m``."""

    def to_metres(self, raw: np.ndarray, camera: Camera) -> np.ndarray:
        """Metric depth float32 (H, W) from the raw output (H, W); non-positive or non-finite -> 0."""
        raw = np.asarray(raw, dtype=np.float64)
        inverse = self.kind == "relative-inverse"
        if self.kind == "metric":
            depth = raw
        elif self.camera_height_m is not None:
            from cuboidcli.depth.scale import scale_from_camera_height

            with np.errstate(divide="ignore", invalid="ignore"):
                unscaled = 1.0 / raw if inverse else raw  # shift 0: depth up to scale
            unscaled = np.where(np.isfinite(unscaled) & (unscaled > 0), unscaled, 0.0)
            self.floor = scale_from_camera_height(unscaled, camera, self.camera_height_m)
            depth = self.floor.scale * unscaled
        else:
            if self.ref_depth is not None:
                scale, shift, n = fit_scale_shift(raw, self.ref_depth, inverse)
                self.alignment = (scale, shift, n)
            else:
                scale, shift = self.scale, self.shift or 0.0
            aligned = scale * raw + shift
            with np.errstate(divide="ignore", invalid="ignore"):
                depth = 1.0 / aligned if inverse else aligned
        depth = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0)
        return depth.astype(np.float32)

    def describe(self) -> str:
        """The kind and how it was scaled, e.g. "relative-inverse, scale 2, shift 0"."""
        if self.kind == "metric":
            return "metric"
        if self.camera_height_m is not None:
            text = f"{self.kind}, scaled to a camera {self.camera_height_m:g} m above the floor"
            if self.floor is not None:
                text += (
                    f" (floor at {self.floor.floor_distance:.4g} model units: scale {self.floor.scale:.4g})"
                )
            return text
        if self.ref_depth is not None:
            if self.alignment is None:
                return f"{self.kind}, aligned to the partial depth map"
            s, b, n = self.alignment
            return (
                f"{self.kind}, aligned to the partial depth map over {n} pixels: scale {s:.4g}, shift {b:.4g}"
            )
        return f"{self.kind}, scale {self.scale:g}, shift {self.shift or 0.0:g}"


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

    # kept for callers of the previous attributes
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
        if inputs[0].type not in ("tensor(float)", "tensor(float16)", "tensor(double)"):
            raise ValueError(f"the depth model's input is {inputs[0].type}; expected a float tensor")
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
        """Refuse a first output whose declared shape cannot be a depth map (one line)."""
        shape = list(self.session.get_outputs()[0].shape)
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


def check_alignment_args(kind: str, scale, shift, ref_depth, camera_height_m=None) -> None:
    """One-line ValueError unless ``kind`` and its scale sources fit together (:class:`DepthScaling`)."""
    if kind not in KINDS:
        raise ValueError(f"unknown depth model kind {kind!r}; choose one of {', '.join(KINDS)}")
    given = scale is not None or shift is not None
    height = camera_height_m is not None
    if kind == "metric":
        if given or ref_depth is not None or height:
            raise ValueError(
                "a metric depth model needs no scale, shift, partial depth or camera height; "
                "use kind 'relative'"
            )
        return
    if given + (ref_depth is not None) + height > 1:
        raise ValueError(
            "give one of a scale (and shift), a partial depth map to fit them to, or the camera height, "
            "not both"
        )
    if not given and ref_depth is None and not height:
        raise ValueError(
            f"a {kind} depth model gives depth only up to scale: it needs a scale (--relative-scale), a "
            "partial depth map to align its output to (--partial-depth), or the camera's height above the "
            "floor (--camera-height)"
        )
    if shift is not None and scale is None:
        raise ValueError("a shift needs a scale as well (pass scale 1 for a shift alone)")
    if scale is not None and not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"the depth scale must be a positive number, got {scale}")
    if height and not (math.isfinite(camera_height_m) and camera_height_m > 0):
        raise ValueError(f"the camera height must be a positive number of metres, got {camera_height_m}")


def fit_scale_shift(
    raw: np.ndarray, ref_depth: np.ndarray, inverse: bool = False
) -> tuple[float, float, int]:
    """Least-squares (scale, shift) with scale * raw + shift ~ ref_depth (or ~ 1 / ref_depth if
    ``inverse``) over the pixels where the reference is finite and positive and ``raw`` is finite.

    raw, ref_depth: (H, W). Returns (scale, shift, number of pixels used). Raises ValueError for a
    reference of the wrong size, too few pixels, a constant model output or a non-positive scale.
    """
    ref = np.asarray(ref_depth, dtype=np.float64)
    if ref.shape != raw.shape:
        raise ValueError(
            f"the partial depth map has shape {ref.shape} but the image is {raw.shape[1]}x{raw.shape[0]} "
            f"(expected {raw.shape}); the depth map must be registered to the image"
        )
    mask = np.isfinite(ref) & (ref > 0) & np.isfinite(raw)
    n = int(mask.sum())
    if n < 2:
        raise ValueError(
            f"the partial depth map has {n} valid pixels; at least 2 are needed to fit scale and shift"
        )
    target = 1.0 / ref[mask] if inverse else ref[mask]
    x = raw[mask]
    a = np.stack([x, np.ones_like(x)], 1)
    if np.ptp(x) <= 1e-12 * max(1.0, float(np.abs(x).max())):
        raise ValueError(
            "the depth model's output is constant on the partial depth's pixels; cannot fit a scale"
        )
    (scale, shift), *_ = np.linalg.lstsq(a, target, rcond=None)
    if scale <= 0:
        hint = "relative" if inverse else "relative-inverse"
        raise ValueError(
            f"aligning the model's output to the partial depth gave a negative scale ({scale:.3g}); "
            f"does the model predict the other kind? try '{hint}'"
        )
    return float(scale), float(shift), n


def estimate_depth(
    estimator: DepthEstimator, rgb: np.ndarray, camera: Camera, timing: dict | None = None
) -> tuple[np.ndarray, str]:
    """Depth for ``fit_depth`` from an RGB image with a built estimator: ``(depth_m float32 (H, W), one-line
    description)``. ``timing``: a dict that receives ``"depth"``, the seconds of the estimation itself.
    Raises ValueError when the estimate has no positive depth."""
    t0 = time.perf_counter()
    depth = estimator.predict(rgb, camera)
    if timing is not None:
        timing["depth"] = time.perf_counter() - t0
    if not (depth > 0).any():
        raise ValueError(f"{estimator.describe()}: the estimated depth has no positive values")
    return depth, estimator.describe()

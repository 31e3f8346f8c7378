"""Depth estimators f_v (paper Sec. 3): an RGB image in, a metric depth map for the fitting pipeline out.

Every estimator implements :class:`DepthEstimator`: ``predict(rgb, camera)`` with ``rgb`` an ``(H, W, 3)``
uint8 RGB image and ``camera`` its intrinsics (``camera.width x camera.height == W x H``) returns depth in
metres, float32 ``(H, W)`` at the image's full resolution; 0 marks pixels without a usable estimate. The
fitting pipeline subsamples this map to its fitting grid (every 8th pixel) itself.

- :class:`BuiltinDepthEstimator`: the project's own network (:mod:`cuboidcli.nets.depth`), from a weights
  file or a loaded net (the default file, ``models/depth_v3.pt``, is the weights registry's:
  :func:`cuboidcli.factories.make_depth_estimator` builds an estimator for a ``--depth-model`` value).
- :class:`OnnxDepthEstimator`: a user's monocular network exported to ONNX. Expected tensors:

  * input: one tensor ``(1, 3, h, w)`` float32, RGB order, ``(rgb / 255 - mean) / std`` per channel
    (``mean``/``std`` default to the ImageNet statistics; pass (0, 0, 0) and (1, 1, 1) for plain [0, 1]).
    ``h, w`` fixed in the model: the image is resized to them and the output resized back; dynamic: the
    image is fed at its own size (or at ``input_size``).
  * output: the first output, ``(1, 1, h', w')``, ``(1, h', w')`` or ``(h', w')`` float32, resized
    bilinearly to the image size if different. ``kind`` says what it holds: ``metric`` depth in metres;
    ``relative`` depth up to an unknown scale and shift (d = scale * r + shift, m); ``relative-inverse``
    inverse depth up to scale and shift (1 / d = scale * r + shift, 1/m; MiDaS / Depth Anything style).
    Relative outputs are aligned with a given scale (and shift), or by least squares to a partial
    reference depth map over the reference's valid pixels.
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
    """Monocular depth: ``predict(rgb (H, W, 3) uint8, camera) -> depth_m (H, W) float32``, 0 = unknown."""

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


class OnnxDepthEstimator:
    """A user's monocular depth network in ONNX (tensor layout in the module docstring).

    ``kind``: metric | relative | relative-inverse. Relative outputs need ``scale`` (and optionally
    ``shift``, default 0) or ``ref_depth``: a partial depth map (H, W) in metres, 0/NaN where unknown, to
    which scale and shift are fitted by least squares. ``mean``/``std``: the input normalisation.
    ``input_size``: (h, w) to feed a model with dynamic spatial axes (default: the image's size).
    Depth that comes out non-positive or non-finite after alignment is reported as 0 (unknown).
    """

    def __init__(
        self,
        path: str | os.PathLike,
        kind: str = "metric",
        scale: float | None = None,
        shift: float | None = None,
        ref_depth: np.ndarray | None = None,
        mean=IMAGENET_MEAN,
        std=IMAGENET_STD,
        input_size: tuple[int, int] | None = None,
    ) -> None:
        _check_alignment_args(kind, scale, shift, ref_depth)
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
        self.kind, self.scale, self.shift, self.ref_depth = kind, scale, shift, ref_depth
        self.mean, self.std, self.input_size = mean, std, input_size
        try:
            self.session = ort.InferenceSession(str(self.path), providers=["CPUExecutionProvider"])
        except Exception as e:  # onnxruntime raises its own exception types for unreadable models
            raise ValueError(f"cannot load ONNX model {self.path}: {str(e).splitlines()[0]}") from e
        self.input_name, self.fixed_hw = self._inspect_input()
        self.alignment: tuple[float, float, int] | None = None
        """(scale, shift, pixels) of the last least-squares fit to ``ref_depth``."""

    def _inspect_input(self) -> tuple[str, tuple[int, int] | None]:
        inputs = self.session.get_inputs()
        if len(inputs) != 1:
            names = ", ".join(i.name for i in inputs)
            raise ValueError(
                f"the depth model must take one input (an RGB image), it takes {len(inputs)}: {names}"
            )
        shape = list(inputs[0].shape)
        if len(shape) != 4:
            raise ValueError(f"the depth model's input has shape {shape}; expected (1, 3, H, W)")
        n, c, h, w = shape
        if isinstance(c, int) and c != 3:
            raise ValueError(f"the depth model's input has {c} channels; expected 3 (RGB), NCHW layout")
        if isinstance(n, int) and n != 1:
            raise ValueError(f"the depth model's input has a fixed batch of {n}; expected 1 or dynamic")
        fixed = (h, w) if isinstance(h, int) and isinstance(w, int) else None
        return inputs[0].name, fixed

    def raw_output(self, rgb: np.ndarray, camera: Camera) -> np.ndarray:
        """The model's output (before alignment), resized to the image: float64 (H, W)."""
        check_rgb(rgb, camera)
        h, w = self.fixed_hw or self.input_size or rgb.shape[:2]
        x = _normalised_nchw(resize(rgb, h, w), self.mean, self.std)
        try:
            out = self.session.run(None, {self.input_name: x})[0]
        except Exception as e:  # a model that rejects the size raises an onnxruntime error
            raise ValueError(f"the depth model failed on a {w}x{h} input: {str(e).splitlines()[0]}") from e
        out = np.asarray(out)
        while out.ndim > 2 and out.shape[0] == 1:
            out = out[0]
        if out.ndim != 2:
            raise ValueError(
                f"the depth model's output has shape {out.shape}; expected (1, 1, H, W), (1, H, W) or (H, W)"
            )
        return resize(out.astype(np.float32), camera.height, camera.width).astype(np.float64)

    def predict(self, rgb: np.ndarray, camera: Camera) -> np.ndarray:
        """Metric depth at the image's resolution, float32 (H, W), metres; 0 where unknown."""
        r = self.raw_output(rgb, camera)
        if self.kind == "metric":
            depth = r
        else:
            inverse = self.kind == "relative-inverse"
            if self.ref_depth is not None:
                scale, shift, n = fit_scale_shift(r, self.ref_depth, inverse)
                self.alignment = (scale, shift, n)
            else:
                scale, shift = self.scale, self.shift or 0.0
            aligned = scale * r + shift
            with np.errstate(divide="ignore", invalid="ignore"):
                depth = 1.0 / aligned if inverse else aligned
        depth = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0)
        return depth.astype(np.float32)

    def describe(self) -> str:
        text = f"depth estimated from RGB by {self.path.name} ({self.kind}"
        if self.kind == "metric":
            return text + ")"
        if self.ref_depth is not None:
            if self.alignment is None:
                return text + ", aligned to the partial depth map)"
            s, b, n = self.alignment
            return text + f", aligned to the partial depth map over {n} pixels: scale {s:.4g}, shift {b:.4g})"
        return text + f", scale {self.scale:g}, shift {self.shift or 0.0:g})"


def _check_alignment_args(kind: str, scale, shift, ref_depth) -> None:
    if kind not in KINDS:
        raise ValueError(f"unknown depth model kind {kind!r}; choose one of {', '.join(KINDS)}")
    given = scale is not None or shift is not None
    if kind == "metric":
        if given or ref_depth is not None:
            raise ValueError(
                "a metric depth model needs no scale, shift or partial depth; use kind 'relative'"
            )
        return
    if given and ref_depth is not None:
        raise ValueError("give either a scale (and shift) or a partial depth map to fit them to, not both")
    if not given and ref_depth is None:
        raise ValueError(
            f"a {kind} depth model needs a scale (and shift) or a partial depth map to align its output to"
        )
    if shift is not None and scale is None:
        raise ValueError("a shift needs a scale as well (pass scale 1 for a shift alone)")
    if scale is not None and not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"the depth scale must be a positive number, got {scale}")


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

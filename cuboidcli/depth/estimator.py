"""Depth estimators f_v (paper Sec. 3): an RGB image in, a metric depth map for the fitting pipeline out.

Every estimator implements :class:`DepthEstimator`: ``predict(rgb, camera)`` with ``rgb`` an ``(H, W, 3)``
uint8 RGB image and ``camera`` its intrinsics (``camera.width x camera.height == W x H``) returns depth in
metres, float32 ``(H, W)`` at the image's full resolution; 0 marks pixels without a usable estimate. The
fitting pipeline subsamples this map to its fitting grid (every 8th pixel) itself.

- :class:`BuiltinDepthEstimator`: the project's own network (:mod:`cuboidcli.nets.depth`), from a weights
  file or a loaded net (the default file, ``models/depth_v4.pt``, is the weights registry's:
  :func:`cuboidcli.factories.make_depth_estimator` builds an estimator for a ``--depth-model`` value).
- :class:`cuboidcli.depth.onnx.OnnxDepthEstimator`: a user's monocular network exported to ONNX (its
  tensor conventions and named presets there).
- :class:`cuboidcli.depth.hf.HFDepthEstimator`: a Hugging Face ``transformers`` depth-estimation model
  (Depth Anything, DPT, ZoeDepth, GLPN, Depth Pro), from a ``save_pretrained`` folder or ``hf:owner/name``.

Relative outputs (ONNX and Hugging Face models) become metres through
:class:`cuboidcli.depth.scale.DepthScaling`; the image checks and resizing all estimators share are
:mod:`cuboidcli.depth.image`.
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
from cuboidcli.depth.image import check_rgb, resize
from cuboidcli.nets.depth import DepthNet, net_from_checkpoint


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

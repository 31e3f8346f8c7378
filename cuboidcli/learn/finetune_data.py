"""The training frames of end-to-end fine-tuning (:mod:`cuboidcli.learn.finetune`): the true fitting
points of each frame and, for fine-tuning from RGB, its image at the depth network's input size."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch
from torch import Tensor

from cuboidcli.camera import Camera
from cuboidcli.fitting.prepare import prepare_points
from cuboidcli.io.dataset import Frame


@dataclass
class Scene:
    """A training frame: true fitting points Z, the grid, and (RGB) the image and pixel coordinates."""

    name: str
    camera: Camera
    z_points: Tensor  # (N, 3) float64, m
    grid_index: Tensor  # (N,) long
    grid_shape: tuple[int, int]
    depth_grid: Tensor  # (Hs, Ws) float32, true depth on the grid (0 = invalid)
    grid_step: int
    rgb: Tensor | None = None  # (1, 3, h, w) float32 in [0, 1] at the depth net's input size
    uv: Tensor | None = None  # (N, 2) float64 pixel coordinates of the fitting points


def load_scene(frame: Frame, grid_step: int, rgb_size: tuple[int, int] | None) -> Scene | None:
    """Read a frame; None when it has fewer than 6 valid points (or no RGB when ``rgb_size``)."""
    depth = frame.depth_m()
    prep = prepare_points(depth, frame.camera, grid_step).as_tensors()  # training computes with torch
    if prep.points.shape[0] < 6:
        return None
    scene = Scene(
        frame.name,
        frame.camera,
        prep.points.double(),
        prep.grid.index,
        prep.grid.shape,
        prep.grid.depth.float(),
        grid_step,
    )
    if rgb_size is not None:
        from cuboidcli.depth.image import resize

        image = frame.rgb()
        if image is None:
            return None
        small = resize(image, *rgb_size)
        scene.rgb = torch.from_numpy(np.ascontiguousarray(small)).permute(2, 0, 1)[None].float() / 255.0
        u, v = frame.camera.pixel_grid(grid_step)
        uv = np.stack([u.reshape(-1), v.reshape(-1)], 1)[prep.grid.index.numpy()]
        scene.uv = torch.from_numpy(uv)
    return scene


def has_rgb(frame) -> bool:
    """Whether a frame has a colour image (dataset folders: an rgb file; NYU's .mat: always)."""
    return getattr(frame, "rgb_path", True) is not None

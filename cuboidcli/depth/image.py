"""The RGB image a depth estimator takes: its check and its resizing to a network's input size."""

from __future__ import annotations

import numpy as np

from cuboidcli.camera import Camera


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

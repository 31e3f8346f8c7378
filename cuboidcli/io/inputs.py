"""Which files of a folder ``cuboids fit DIR`` fits: its depth maps, or its colour photos (depth estimated
from them). A folder of frames often holds both kinds side by side (NYU, TUM: ``x_rgb.jpg`` next to
``x_depth.png``); a photo folder's depth maps and other one-channel images are left out."""

from __future__ import annotations

from pathlib import Path

from cuboidcli.io.dataset import DEPTH_SUFFIXES

#: File endings taken for images (a photo, or a depth PNG before its channels are looked at).
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


def _files(folder: Path, suffixes: tuple[str, ...]) -> list[Path]:
    return sorted(p for p in Path(folder).iterdir() if p.suffix.lower() in suffixes and p.is_file())


def depth_maps_in(folder: str | Path) -> list[Path]:
    """The depth maps of a folder (.png, .npy, .npz, .exr), sorted by name."""
    return _files(Path(folder), DEPTH_SUFFIXES)


def is_colour_image(path: str | Path) -> bool:
    """Whether ``path`` is a colour image (3 or 4 channels); a one-channel PNG is taken for a depth map."""
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    return img is not None and img.ndim == 3 and img.shape[2] in (3, 4)


def photos_in(folder: str | Path) -> tuple[list[Path], int]:
    """The colour images of a folder, sorted by name, and how many other images (16-bit or grey: depth
    maps) were left out."""
    images = _files(Path(folder), IMAGE_SUFFIXES)
    photos = [p for p in images if is_colour_image(p)]
    return photos, len(images) - len(photos)


def has_images(folder: str | Path) -> bool:
    """Whether any file of the folder has an image's ending (a folder of frames, not of rooms)."""
    return any(p.suffix.lower() in IMAGE_SUFFIXES for p in Path(folder).iterdir())

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


def depth_maps_in(folder: str | Path) -> tuple[list[Path], int]:
    """The depth maps of a folder (.png, .npy, .npz, .exr), sorted by name, and how many colour PNGs (the
    frames' photos beside their depth maps) were left out."""
    files = _files(Path(folder), DEPTH_SUFFIXES)
    maps = [p for p in files if not _colour_png(p)]
    return maps, len(files) - len(maps)


def _colour_png(path: Path) -> bool:
    """Whether ``path`` is a PNG of colour type RGB, palette or RGBA, read from its header alone (a depth
    map is a one-channel PNG)."""
    if path.suffix.lower() != ".png":
        return False
    with open(path, "rb") as f:
        head = f.read(26)
    # the 8-byte signature, then the IHDR chunk: length, type, width, height, bit depth, colour type
    return (
        len(head) == 26
        and head[:8] == b"\x89PNG\r\n\x1a\n"
        and head[12:16] == b"IHDR"
        and head[25] in (2, 3, 6)
    )


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

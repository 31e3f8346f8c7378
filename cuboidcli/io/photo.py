"""Reading a photo and its camera: upright pixels (EXIF orientation applied) and intrinsics from EXIF.

The intrinsics come from, in this order: ``FocalLengthIn35mmFilm`` (fx = fy = f35 / 36 mm times the long
side in pixels), or ``FocalLength`` with the sensor's ``FocalPlaneX/YResolution``; both describe the
image as it is shown (axes swapped for orientations 5-8) with the principal point at its centre. When
neither is there the caller falls back to :func:`default_camera`. Pillow reads the image and its EXIF.
"""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.io.depth import InputError, _one_line

DEFAULT_FOV_DEG = 63.0
"""Field of view across the long side assumed when neither the user, the photo's EXIF nor the depth model
says anything about the lens: that of the Kinect-class cameras of the real frames we check against (NYU
63.3, TUM and Redwood 62.7 degrees), a little narrower than a phone's main camera (69 degrees at 26 mm
equivalent; phones write EXIF, so their photos rarely fall back to this). A 640x480 frame gets fx = 522 px
(NYU's is 519)."""

#: Range of plausible fields of view (degrees, across the long side); EXIF focal lengths outside it are
#: treated as corrupt.
FOV_RANGE_DEG = (10.0, 150.0)

#: EXIF FocalPlaneResolutionUnit values: millimetres per unit.
_MM_PER_UNIT = {2: 25.4, 3: 10.0, 4: 1.0, 5: 0.001}

_SWAPS_AXES = (5, 6, 7, 8)


@dataclass
class Photo:
    """An RGB photo (H, W, 3) uint8, upright, with what its EXIF says about the camera."""

    rgb: np.ndarray
    orientation: int = 1
    """The EXIF Orientation applied to the stored pixels (1: none, or no valid tag)."""
    exif_camera: Camera | None = None
    """The camera of the upright image from EXIF (``source`` starts with "exif:"); None when unknown."""
    notes: list[str] = field(default_factory=list)
    """One-line warnings, e.g. a corrupt EXIF tag that was ignored."""


def read_photo(path: str | os.PathLike) -> Photo:
    """The photo at ``path``, upright, with intrinsics from its EXIF when it has usable ones.

    Greyscale, palette and RGBA images become RGB (alpha dropped; 16-bit colour PNGs reduced to 8 bits);
    single-channel 16-bit or float images (depth maps) and unreadable files raise :class:`InputError`.
    """
    from PIL import Image, UnidentifiedImageError

    path = Path(path)
    if not path.is_file():
        raise InputError(f"image file not found: {path}")
    notes: list[str] = []
    try:
        with Image.open(path) as im:
            im.load()
            stored_w, stored_h = im.size
            tags, orientation = _exif_tags(im, notes)
            img = _to_rgb(im, path)
            if orientation != 1:
                img = img.transpose(_transpose_methods()[orientation])
            rgb = np.array(img, dtype=np.uint8)
    except InputError:
        raise
    except UnidentifiedImageError as e:
        raise InputError(f"cannot decode image {path} (corrupt or not an image file)") from e
    except (OSError, ValueError, SyntaxError, EOFError, Image.DecompressionBombError) as e:
        raise InputError(f"cannot decode image {path} ({_one_line(e)})") from e
    camera = exif_intrinsics(tags, stored_w, stored_h, orientation, notes)
    return Photo(rgb, orientation, camera, notes)


def default_camera(width: int, height: int, fov_deg: float = DEFAULT_FOV_DEG) -> Camera:
    """A pinhole with ``fov_deg`` across the long side, square pixels, principal point at the centre."""
    if width <= 0 or height <= 0:
        raise InputError(f"image size {width}x{height} must be positive")
    if not 0.0 < fov_deg < 180.0:
        raise InputError(f"field of view {fov_deg:g} degrees must be between 0 and 180")
    f = max(width, height) / 2.0 / math.tan(math.radians(fov_deg) / 2.0)
    source = f"default: {fov_deg:g} degree field of view across the long side"
    return _centred(f, f, width, height, source)


def exif_intrinsics(
    tags: dict, stored_w: int, stored_h: int, orientation: int = 1, notes: list[str] | None = None
) -> Camera | None:
    """The camera of the upright image from EXIF ``tags`` (tag number -> value, as Pillow reads them)
    of an image stored as ``stored_w`` x ``stored_h`` pixels; None when the tags needed are missing.

    Corrupt or absurd tags are skipped with one line each in ``notes``, falling through to the next rule.
    """
    notes = [] if notes is None else notes
    swap = orientation in _SWAPS_AXES
    w, h = (stored_h, stored_w) if swap else (stored_w, stored_h)
    f35 = _positive(tags, 41989, "FocalLengthIn35mmFilm", notes)
    if f35 is not None:
        f = f35 / 36.0 * max(w, h)
        if _plausible(f, f, w, h, f"FocalLengthIn35mmFilm = {f35:g} mm", notes):
            return _centred(f, f, w, h, f"exif: FocalLengthIn35mmFilm {f35:g} mm")
    focal_mm = _positive(tags, 37386, "FocalLength", notes)
    xres = _positive(tags, 41486, "FocalPlaneXResolution", notes)
    if focal_mm is None or xres is None:
        return None
    yres = _positive(tags, 41487, "FocalPlaneYResolution", notes) or xres
    unit = tags.get(41488, 2)  # EXIF's default unit is the inch
    if unit not in _MM_PER_UNIT:
        notes.append(f"EXIF FocalPlaneResolutionUnit = {unit!r} is not 2-5 (inch, cm, mm, um); ignored")
        return None
    # The resolution counts pixels of the image the camera wrote (PixelX/YDimension); a resized copy
    # that kept the EXIF has proportionally fewer. The long sides compare whatever the orientation.
    ref_w = _positive(tags, 40962, "PixelXDimension", notes)
    ref_h = _positive(tags, 40963, "PixelYDimension", notes)
    scale = 1.0
    if ref_w is not None and ref_h is not None:
        scale = max(stored_w, stored_h) / max(ref_w, ref_h)
    elif ref_w is not None:
        scale = stored_w / ref_w
    fx = focal_mm * xres / _MM_PER_UNIT[unit] * scale
    fy = focal_mm * yres / _MM_PER_UNIT[unit] * scale
    if swap:
        fx, fy = fy, fx
    what = f"FocalLength = {focal_mm:g} mm with FocalPlaneXResolution = {xres:g} per unit {unit}"
    if not _plausible(fx, fy, w, h, what, notes):
        return None
    return _centred(fx, fy, w, h, f"exif: FocalLength {focal_mm:g} mm, FocalPlaneXResolution {xres:g}")


def centred_intrinsics(focal_px: float, width: int, height: int, source: str) -> Camera:
    """Square pixels of ``focal_px`` with the principal point at the centre of a ``width`` x ``height``
    image (e.g. the focal length a depth model predicts); InputError for a focal length that is not a
    positive finite number."""
    if not (math.isfinite(focal_px) and focal_px > 0):
        raise InputError(f"{source}: the focal length {focal_px} px is not a positive number")
    return _centred(focal_px, focal_px, width, height, source)


def _centred(fx: float, fy: float, w: int, h: int, source: str) -> Camera:
    """Principal point at the image centre, pixel-centre convention (as Camera.scaled)."""
    return Camera(fx, fy, (w - 1) / 2.0, (h - 1) / 2.0, int(w), int(h), source=source)


def _plausible(fx: float, fy: float, w: int, h: int, what: str, notes: list[str]) -> bool:
    f_long = fx if w >= h else fy
    fov = math.degrees(2.0 * math.atan(max(w, h) / (2.0 * f_long)))
    lo, hi = FOV_RANGE_DEG
    if not lo <= fov <= hi:
        notes.append(f"EXIF {what} implies a {fov:.1f} degree field of view (not {lo:g}-{hi:g}); ignored")
        return False
    if not 0.5 <= fx / fy <= 2.0:
        notes.append(f"EXIF {what} implies pixels {fx / fy:.2f} times as wide as tall; ignored")
        return False
    return True


def _positive(tags: dict, tag: int, name: str, notes: list[str]) -> float | None:
    """The tag as a positive finite number; None (with a note unless it is missing) otherwise."""
    if tag not in tags:
        return None
    value = tags[tag]
    if isinstance(value, tuple) and len(value) == 1:
        value = value[0]
    if getattr(value, "denominator", 1) == 0:
        notes.append(f"EXIF {name} is a fraction with a zero denominator; ignored")
        return None
    try:
        number = float(value)
    except (TypeError, ValueError, ZeroDivisionError):
        notes.append(f"EXIF {name} = {value!r:.40} is not a number; ignored")
        return None
    if not math.isfinite(number) or number <= 0:
        notes.append(f"EXIF {name} = {number:g} is not a positive number; ignored")
        return None
    return number


def _exif_tags(im, notes: list[str]) -> tuple[dict, int]:
    """The image's EXIF tags (IFD0 with the Exif IFD over it) and its valid orientation (1 if none)."""
    from PIL import ExifTags

    try:
        exif = im.getexif()
        tags = {**dict(exif), **dict(exif.get_ifd(ExifTags.IFD.Exif))}
    except Exception as e:  # Pillow raises assorted errors for malformed EXIF blocks
        notes.append(f"EXIF data unreadable ({_one_line(e)}); ignored")
        return {}, 1
    orientation = tags.get(274, 1)
    if orientation not in range(1, 9):
        notes.append(f"EXIF Orientation = {orientation!r:.40} is not 1-8; image used as stored")
        orientation = 1
    return tags, int(orientation)


def _to_rgb(im, path: Path):
    """8-bit RGB Pillow image; single-channel 16-bit / 32-bit / float images are refused."""
    if im.mode in ("I", "F") or im.mode.startswith("I;"):
        raise InputError(
            f"{path} is a single-channel {im.mode} image, not an 8-bit colour photo; "
            f"if it is a depth map, pass it with --depth: cuboids fit --depth {path}"
        )
    return im if im.mode == "RGB" else im.convert("RGB")


def _transpose_methods():
    from PIL import Image

    t = Image.Transpose
    # EXIF orientation -> the transpose that shows the stored pixels upright (as ImageOps.exif_transpose).
    return {
        2: t.FLIP_LEFT_RIGHT,
        3: t.ROTATE_180,
        4: t.FLIP_TOP_BOTTOM,
        5: t.TRANSPOSE,
        6: t.ROTATE_270,
        7: t.TRANSVERSE,
        8: t.ROTATE_90,
    }

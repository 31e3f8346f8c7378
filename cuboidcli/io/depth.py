"""Reading depth maps, RGB images and intrinsics, with sanity checks a user can act on.

Depth files: 16-bit PNG (scaled by ``depth_scale`` metres per unit), ``.npy`` / ``.npz`` in metres,
``.exr`` in metres (optional OpenEXR package: ``pip install 'cuboids[exr]'``). 0, NaN and inf mean
missing. Every problem raises :class:`InputError` with a one-line message.
"""

from __future__ import annotations

import math
import os
import warnings
import zipfile
from dataclasses import replace
from pathlib import Path

import numpy as np

from cuboidcli.camera import PRESETS, Camera, valid_depth
from cuboidcli.io.jsonfile import misspelled, read_json, unknown_keys, warn_once


class InputError(ValueError):
    """A problem with the user's input; the message is one line saying what to pass instead."""


class InputWarning(UserWarning):
    """Suspicious but usable input."""


def _one_line(exc: BaseException) -> str:
    return " ".join(str(exc).split()) or type(exc).__name__


def _finite(intr: Camera, what: str) -> Camera:
    values = {"fx": intr.fx, "fy": intr.fy, "cx": intr.cx, "cy": intr.cy}
    bad = [k for k, v in values.items() if not math.isfinite(v)]
    if bad:
        raise InputError(f"{what}: {bad[0]} = {values[bad[0]]} is not a finite number of pixels")
    return intr


def _imread_unchanged(path: Path) -> np.ndarray:
    import cv2

    data = np.fromfile(str(path), dtype=np.uint8)
    img = cv2.imdecode(data, cv2.IMREAD_UNCHANGED) if data.size else None
    if img is None:
        raise InputError(f"cannot decode image {path} (corrupt or not an image file)")
    return img


def _read_exr(path: Path) -> np.ndarray:
    """First depth-like channel of an OpenEXR file (Z, depth, R, Y, or the only one), in metres."""
    try:
        import OpenEXR
    except ImportError as e:
        raise InputError(
            f"reading {path.name} needs the optional OpenEXR package: pip install 'cuboids[exr]'"
        ) from e
    try:
        with OpenEXR.File(str(path)) as f:
            channels = f.channels()
            for name in ("Z", "depth", "Depth", "R", "Y", *channels.keys()):
                if name in channels:
                    data = np.asarray(channels[name].pixels)
                    return data[..., 0] if data.ndim == 3 else data
    except Exception as e:  # OpenEXR raises plain exceptions for corrupt files
        raise InputError(f"cannot decode EXR file {path}: {e}") from e
    raise InputError(f"{path} holds no image channels")


#: The names an ``.npz`` depth map's array may have; a file with one array may name it anything.
NPZ_DEPTH_KEYS = ("depth", "depth_m")


def _npz_depth(path: Path, z) -> np.ndarray:
    """The depth array of an opened ``.npz``: the one named as :data:`NPZ_DEPTH_KEYS`, else the only one."""
    named = [k for k in NPZ_DEPTH_KEYS if k in z.files]
    takes = f"save the depth map as np.savez(f, depth=...) ({' or '.join(NPZ_DEPTH_KEYS)})"
    if len(named) > 1:
        raise InputError(f"{path} holds arrays {' and '.join(named)}; which is the depth map? {takes}")
    if named:
        return z[named[0]]
    if not z.files:
        raise InputError(f"{path} holds no arrays; {takes}")
    if len(z.files) > 1:
        listed = ", ".join(sorted(z.files)[:6]) + (", ..." if len(z.files) > 6 else "")
        raise InputError(f"{path} holds several arrays ({listed}) and none is named depth; {takes}")
    warnings.warn(f"{path}: read its one array {z.files[0]!r} as the depth map", InputWarning, stacklevel=3)
    return z[z.files[0]]


def _depth_array(path: Path, depth: np.ndarray, depth_scale: float) -> np.ndarray:
    """A decoded depth file's array as a depth map in metres (H, W) float32; InputError for an array that
    cannot be one (a shape other than (H, W) or (H, W, 1), no values, not real numbers)."""
    numpy_file = path.suffix.lower() in (".npy", ".npz")
    if depth.ndim == 3 and depth.shape[2] == 1:
        depth = depth[..., 0]
    elif depth.ndim == 3 and depth.shape[2] in (3, 4):
        raise InputError(
            f"{path} has {depth.shape[2]} channels; a depth map has one (is this the RGB image?)"
        )
    if depth.ndim != 2:
        raise InputError(f"{path} has shape {depth.shape}; expected a 2-D depth map (H, W)")
    if depth.size == 0:
        raise InputError(f"{path} holds an empty array (shape {depth.shape}); expected a depth map (H, W)")
    kind = depth.dtype.kind
    if kind == "b":
        raise InputError(f"{path} holds booleans (a mask?); a depth map holds metres (float32)")
    if kind not in "iuf":
        what = "complex numbers" if kind == "c" else f"{depth.dtype} values"
        raise InputError(f"{path} holds {what}; a depth map holds real metres (float32)")
    if kind == "f":
        return depth.astype(np.float32)
    if depth.dtype == np.uint8:
        raise InputError(
            f"{path} is an 8-bit {'array' if numpy_file else 'image'}; depth must be a 16-bit PNG "
            "(or .npy/.npz in metres)"
        )
    if numpy_file:
        warnings.warn(
            f"{path} holds integers ({depth.dtype}), read as depth-PNG units of {depth_scale:g} m "
            "(--depth-scale); .npy/.npz depth in metres is float",
            InputWarning,
            stacklevel=3,
        )
    return depth.astype(np.float32) * np.float32(depth_scale)


def read_depth(path: str | os.PathLike, depth_scale: float = 0.001) -> np.ndarray:
    """Depth map in metres, float32 (H, W); missing values become 0. An ``.npz`` holds it as ``depth``
    (:data:`NPZ_DEPTH_KEYS`) or as its only array; integers (a PNG's, an array's) are units of
    ``depth_scale`` metres."""
    path = Path(path)
    if not path.exists():
        raise InputError(f"depth file not found: {path}")
    if not path.is_file():
        raise InputError(f"depth path is not a file: {path}")
    suffix = path.suffix.lower()
    try:
        if suffix == ".npy":
            depth = np.load(path, allow_pickle=False)
        elif suffix == ".npz":
            with np.load(path, allow_pickle=False) as z:
                depth = _npz_depth(path, z)
        elif suffix == ".exr":
            depth = _read_exr(path)
        else:
            depth = _imread_unchanged(path)
    except InputError:
        raise
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as e:  # truncated or not this format
        raise InputError(f"cannot read depth file {path}: {_one_line(e)}") from e
    depth = _depth_array(path, np.asarray(depth), depth_scale)
    depth[~valid_depth(depth)] = 0.0
    return depth


def read_rgb(path: str | os.PathLike) -> np.ndarray:
    """RGB image (H, W, 3) uint8."""
    import cv2

    path = Path(path)
    if not path.is_file():
        raise InputError(f"image file not found: {path}")
    img = _imread_unchanged(path)
    if img.ndim == 2:
        img = np.repeat(img[..., None], 3, axis=2)
    if img.dtype != np.uint8:
        if img.dtype == np.uint16 and img.ndim == 3:
            img = (img / 257).astype(np.uint8)
        else:
            raise InputError(
                f"{path} is not an 8-bit colour image (dtype {img.dtype}); the depth map goes after --depth, "
                "the colour image before it"
            )
    if img.shape[2] == 4:
        img = img[..., :3]
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def parse_intrinsics(spec: str | None, preset: str | None = None, frame: str | None = None) -> Camera:
    """The camera of ``fx,fy,cx,cy``, a JSON file, or a preset name, with its ``source`` and ``depth_scale``
    (:class:`~cuboidcli.camera.Camera`; width and height 0 where the source gives no size).

    A JSON file holds keys fx, fy, cx, cy (optionally width, height, depth_scale), or a mapping from frame
    names to such entries (as ``cameras.json`` of a dataset folder); ``frame`` selects the entry.
    """
    if spec is None:
        name = preset or "nyu"
        if name not in PRESETS:
            raise InputError(f"unknown preset {name!r}; choose one of: {', '.join(PRESETS)}")
        return Camera.preset(name)
    path = Path(spec)
    if spec.lower().endswith(".json") or path.is_file():
        d = read_json(
            path,
            InputError,
            "intrinsics file {path} is not valid JSON ({e.msg} at line {e.lineno})",
            missing="intrinsics file not found: {path}",
        )
        if isinstance(d, dict) and "fx" not in d:
            entries = {k: v for k, v in d.items() if isinstance(v, dict) and "fx" in v}
            if frame is not None:
                for tag in ("_depth_filled", "_depth_raw", "_depth", "_rgb", "_color", "_colour", "_image"):
                    if frame not in entries and frame.endswith(tag):
                        frame = frame[: -len(tag)]
            if entries:
                others = [k for k in d if k not in entries and not str(k).startswith("_")]
                _warn_once(path, *(f"key {k!r} is no camera (it has no fx); ignored" for k in others))
            if frame is not None and frame in entries:
                d = entries[frame]
            elif len(entries) == 1:
                d = next(iter(entries.values()))
            elif entries:
                raise InputError(
                    f"{path} holds intrinsics for several frames ({', '.join(sorted(entries)[:4])}, "
                    f"...); none is named {frame!r}"
                )
        if not isinstance(d, dict):
            raise InputError(f"intrinsics file {path} must hold an object with fx, fy, cx, cy (got a JSON "
                             f"{type(d).__name__})")  # fmt: skip
        _warn_once(path, *unknown_keys(d, CAMERA_KEYS))
        try:
            intr = Camera(
                float(d["fx"]), float(d["fy"]), float(d["cx"]), float(d["cy"]),
                _pixels(d, "width"), _pixels(d, "height"), _depth_scale(d),
                source=str(path),
            )  # fmt: skip
        except KeyError as e:
            raise InputError(
                f"intrinsics file {path} must hold numbers fx, fy, cx, cy (missing: {e}"
                f"{misspelled(e.args[0], d)})"
            ) from e
        except (TypeError, ValueError, OverflowError) as e:
            raise InputError(
                f"intrinsics file {path} must hold numbers fx, fy, cx, cy (missing or bad: {e})"
            ) from e
        return _finite(intr, f"intrinsics file {path}")
    parts = spec.replace(" ", "").split(",")
    if len(parts) != 4:
        raise InputError(
            f"--intrinsics {spec!r}: give fx,fy,cx,cy in pixels (4 numbers), a JSON file or a preset"
        )
    try:
        fx, fy, cx, cy = (float(p) for p in parts)
    except ValueError as e:
        raise InputError(f"--intrinsics {spec!r}: fx,fy,cx,cy must be numbers") from e
    return _finite(Camera(fx, fy, cx, cy, source="command line"), f"--intrinsics {spec!r}")


#: The keys of a camera in an intrinsics file (keys starting with "_" are comments).
CAMERA_KEYS = ("fx", "fy", "cx", "cy", "width", "height", "depth_scale")


def _warn_once(path: Path, *lines: str) -> None:
    warn_once(path, lines, InputWarning)


def _pixels(d: dict, key: str) -> int:
    """An intrinsics file's image width or height: a whole number of pixels (0 or absent: unknown)."""
    value = d.get(key, 0)
    if isinstance(value, bool) or not isinstance(value, int | float) or value < 0 or value != int(value):
        raise ValueError(f"{key} must be a whole number of pixels, got {value!r}")
    return int(value)


def _depth_scale(d: dict) -> float | None:
    """An intrinsics file's metres per depth-PNG unit, as ``--depth-scale`` allows it."""
    if "depth_scale" not in d:
        return None
    value = float(d["depth_scale"])
    if not 0 < value <= 1:
        raise ValueError(f"depth_scale must be a number > 0 and <= 1 m per unit, got {d['depth_scale']!r}")
    return value


def read_camera(
    intrinsics: str | os.PathLike | None = None,
    *,
    preset: str | None = None,
    frame: str | None = None,
    width: int = 0,
    height: int = 0,
) -> Camera:
    """Camera intrinsics as ``cuboids fit -K`` reads them: ``"fx,fy,cx,cy"`` in pixels or a JSON file (keys
    fx, fy, cx, cy, optionally width, height; or a mapping from frame names to such entries, ``frame``
    picks one), or ``preset`` nyu, tum or scannet. ``width``/``height`` override the file's (0: as the file
    says, else the size of the depth map it is used with). The Python API's ``cb.read_camera``."""
    if intrinsics is None and preset is None:
        raise InputError("give the intrinsics ('fx,fy,cx,cy' or a JSON file) or a preset (nyu, tum, scannet)")
    cam = parse_intrinsics(None if intrinsics is None else str(intrinsics), preset, frame=frame)
    return cam.with_size(width or cam.width, height or cam.height)


#: Aspect ratios within this relative difference count as the same (a preset is then scaled).
ASPECT_TOLERANCE = 0.01


def intrinsics_for_size(intr: Camera, width: int, height: int, preset: str | None = None) -> Camera:
    """``intr`` for a ``width`` x ``height`` image. A preset's intrinsics (``preset`` names it) are scaled
    to the image when its aspect ratio matches (a 1280x960 image gets twice NYU's focal lengths) and refused
    with an InputError when it does not; intrinsics the user wrote (without a size, or a JSON file's) are
    used as given (:func:`check_inputs` warns when a file's size differs)."""
    if preset is None or not intr.sized:
        return intr
    if (intr.width, intr.height) == (width, height):
        return intr
    aspect, wanted = width / height, intr.width / intr.height
    if abs(aspect - wanted) > ASPECT_TOLERANCE * wanted:
        raise InputError(
            f"--camera {preset} is for {intr.width}x{intr.height} images (aspect {wanted:.3f}) but this "
            f"image is {width}x{height} (aspect {aspect:.3f}); give its intrinsics with -K fx,fy,cx,cy"
        )
    scaled = intr.scaled(width / intr.width, height / intr.height)
    return replace(
        scaled, width=width, height=height, depth_scale=intr.depth_scale,
        source=f"{intr.source} scaled to {width}x{height}",
    )  # fmt: skip


def check_inputs(depth_m: np.ndarray, intr: Camera, rgb_shape: tuple[int, ...] | None = None) -> list[str]:
    """Sanity checks of a depth map (H, W) metres, the camera it is fitted with and the size of its RGB image;
    raises InputError for unusable input, returns warnings (one line each)."""
    h, w = depth_m.shape
    notes: list[str] = []
    valid = valid_depth(depth_m)
    n_valid = int(valid.sum())
    if n_valid == 0:
        raise InputError("the depth map has no valid pixels (all zero, NaN or inf)")
    if n_valid < 0.01 * h * w:
        notes.append(f"only {100.0 * n_valid / (h * w):.1f} % of depth pixels are valid")
    med = float(np.median(depth_m[valid]))
    if med > 100.0:
        raise InputError(
            f"median depth is {med:.0f} m: the depth unit looks wrong (millimetres read as metres?); "
            "pass --depth-scale 0.001 for millimetre PNGs or --camera tum for 1/5000 m"
        )
    if med < 0.05:
        raise InputError(
            f"median depth is {med * 1000:.1f} mm: the depth unit looks wrong; check --depth-scale "
            "(0.001 for millimetre PNGs, 0.0002 for TUM)"
        )
    if med > 30.0:
        notes.append(f"median depth is {med:.1f} m: unusually far for an indoor scene; check --depth-scale")
    if intr.fx <= 0 or intr.fy <= 0:
        raise InputError(f"focal lengths must be positive (fx={intr.fx}, fy={intr.fy})")
    if intr.fx < 0.1 * w and intr.fx < 50:
        raise InputError(
            f"fx = {intr.fx:g} looks like a focal length in millimetres; give it in pixels "
            f"(about {0.8 * w:.0f} for a {w}-pixel-wide Kinect image)"
        )
    if intr.fx > 20 * w:
        notes.append(f"fx = {intr.fx:g} px is very long for a {w}-pixel-wide image")
    if not (-0.5 * w <= intr.cx <= 1.5 * w) or not (-0.5 * h <= intr.cy <= 1.5 * h):
        raise InputError(
            f"principal point ({intr.cx:g}, {intr.cy:g}) is far outside the {w}x{h} image; "
            "check the order fx,fy,cx,cy and the image size"
        )
    if intr.sized and (intr.width, intr.height) != (w, h):
        notes.append(
            f"intrinsics are for {intr.width}x{intr.height} but the depth map is {w}x{h}; using them unscaled"
        )
    if rgb_shape is not None and tuple(rgb_shape[:2]) != (h, w):
        raise InputError(
            f"RGB image is {rgb_shape[1]}x{rgb_shape[0]} but the depth map is {w}x{h}; "
            "they must be registered and the same size"
        )
    return notes


def warn_all(notes: list[str]) -> None:
    for n in notes:
        warnings.warn(n, InputWarning, stacklevel=2)

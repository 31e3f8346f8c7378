"""Pinhole camera in the OpenCV convention (x right, y down, z forward), metres and pixels."""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

#: Named intrinsics presets. ``depth_scale`` is metres per depth-PNG unit.
PRESETS: dict[str, dict[str, float]] = {
    # NYU Depth v2 RGB camera (the labelled set is registered to it).
    "nyu": dict(fx=518.8579, fy=519.4696, cx=325.5824, cy=253.7362, width=640, height=480, depth_scale=0.001),
    # TUM RGB-D default ROS intrinsics; depth PNGs hold 5000 units per metre.
    "tum": dict(fx=525.0, fy=525.0, cx=319.5, cy=239.5, width=640, height=480, depth_scale=1.0 / 5000.0),
    # ScanNet depth camera (640x480 depth stream), millimetre PNGs.
    "scannet": dict(fx=577.87, fy=577.87, cx=319.5, cy=239.5, width=640, height=480, depth_scale=0.001),
}


@dataclass(frozen=True)
class Camera:
    """Pinhole intrinsics in pixels for an image of ``width`` x ``height`` pixels.

    ``width``/``height`` 0 (the default) mean "the size of the image it is used with": the Python API
    (:func:`cuboidcli.fit`) takes them from the depth map, and intrinsics a user gives without a size
    (``-K fx,fy,cx,cy``) have none.

    ``depth_scale`` and ``source`` say what the intrinsics came with: the depth unit the same source states
    (a preset, a camera file; None: it states none) and where they came from (``"preset:nyu"``, a file, an
    EXIF tag, a default field of view), for the frame's record and its messages. They travel with the
    camera from the readers (:mod:`cuboidcli.io.depth`, :mod:`cuboidcli.io.photo`) to the frame instead
    of in a second intrinsics type, and are no part of the pinhole: not compared, not shown, not written
    (:meth:`to_dict` is the six numbers).
    """

    fx: float
    fy: float
    cx: float
    cy: float
    width: int = 0
    height: int = 0
    depth_scale: float | None = field(default=None, compare=False, repr=False)
    """Metres per depth-PNG unit, as the intrinsics' source states it; None: it states none."""
    source: str = field(default="", compare=False, repr=False)
    """Where the intrinsics came from, in words (``meta["intrinsics_source"]`` of a fit)."""

    @classmethod
    def preset(cls, name: str) -> Camera:
        if name not in PRESETS:
            raise ValueError(f"unknown camera preset {name!r}; choose one of {', '.join(PRESETS)}")
        p = PRESETS[name]
        return cls(
            p["fx"], p["fy"], p["cx"], p["cy"], int(p["width"]), int(p["height"]), p["depth_scale"],
            f"preset:{name}",
        )  # fmt: skip

    @classmethod
    def from_dict(cls, d: dict) -> Camera:
        return cls(
            float(d["fx"]), float(d["fy"]), float(d["cx"]), float(d["cy"]), int(d["width"]), int(d["height"])
        )

    def to_dict(self) -> dict:
        """The pinhole: fx, fy, cx, cy, width, height (the "camera" of a result file)."""
        return {k: getattr(self, k) for k in ("fx", "fy", "cx", "cy", "width", "height")}

    @property
    def sized(self) -> bool:
        """Whether the size is known (both width and height given)."""
        return bool(self.width and self.height)

    def for_image(self, width: int, height: int) -> Camera:
        """This camera for a ``width`` x ``height`` image: without a size it takes the image's; with another
        size it is a one-line ValueError."""
        if self.width == 0 and self.height == 0:
            return self.with_size(width, height)
        if (self.width, self.height) != (width, height):
            raise ValueError(
                f"the depth map is {width}x{height} but the camera is {self.width}x{self.height}; "
                "give the camera of this image (or leave width and height out)"
            )
        return self

    @property
    def K(self) -> np.ndarray:  # noqa: N802 - the usual symbol
        """3x3 intrinsic matrix."""
        return np.array([[self.fx, 0.0, self.cx], [0.0, self.fy, self.cy], [0.0, 0.0, 1.0]])

    def with_size(self, width: int, height: int) -> Camera:
        return replace(self, width=int(width), height=int(height))

    def scaled(self, sx: float, sy: float | None = None) -> Camera:
        """Intrinsics of the image resized by factors (sx, sy), pixel-centre convention."""
        sy = sx if sy is None else sy
        return Camera(
            self.fx * sx,
            self.fy * sy,
            (self.cx + 0.5) * sx - 0.5,
            (self.cy + 0.5) * sy - 0.5,
            int(round(self.width * sx)),
            int(round(self.height * sy)),
        )

    def pixel_grid(self, step: int = 1) -> tuple[np.ndarray, np.ndarray]:
        """Pixel coordinates (u, v) of every ``step``-th pixel, each of shape (H', W')."""
        us = np.arange(0, self.width, step, dtype=np.float64)
        vs = np.arange(0, self.height, step, dtype=np.float64)
        return np.meshgrid(us, vs)

    def backproject(self, depth_m: np.ndarray, step: int = 1) -> np.ndarray:
        """Back-project a depth map (H, W) in metres to points (H', W', 3) in camera coordinates.

        ``step`` takes every step-th pixel (nearest, no averaging) as the paper's fitting grid does.
        Invalid depth stays NaN/0 in z; callers mask with :func:`valid_depth`.
        """
        if depth_m.shape != (self.height, self.width):
            raise ValueError(
                f"depth map is {depth_m.shape[1]}x{depth_m.shape[0]} but the camera is "
                f"{self.width}x{self.height}"
            )
        return self.backproject_grid(depth_m[::step, ::step], step)

    def backproject_grid(self, depth_grid_m: np.ndarray, step: int) -> np.ndarray:
        """Back-project the depth of every ``step``-th pixel, already taken (``depth_m[::step, ::step]``,
        shape (ceil(H / step), ceil(W / step))), to points (H', W', 3) in camera coordinates."""
        z = depth_grid_m.astype(np.float64)
        u, v = self.pixel_grid(step)
        if z.shape != u.shape:
            raise ValueError(
                f"a step-{step} grid of a {self.width}x{self.height} camera is {u.shape}, not {z.shape}"
            )
        x = (u - self.cx) / self.fx * z
        y = (v - self.cy) / self.fy * z
        return np.stack([x, y, z], axis=-1)

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Project points (..., 3) to pixel coordinates (..., 2); returns (uv, z)."""
        z = points[..., 2]
        with np.errstate(divide="ignore", invalid="ignore"):
            u = self.fx * points[..., 0] / z + self.cx
            v = self.fy * points[..., 1] / z + self.cy
        return np.stack([u, v], axis=-1), z

    def fov_deg(self) -> tuple[float, float]:
        return (
            math.degrees(2 * math.atan(self.width / (2 * self.fx))),
            math.degrees(2 * math.atan(self.height / (2 * self.fy))),
        )


def valid_depth(depth_m: np.ndarray) -> np.ndarray:
    """Mask of usable depth: finite and strictly positive (0, NaN and inf mean missing)."""
    return np.isfinite(depth_m) & (depth_m > 0)

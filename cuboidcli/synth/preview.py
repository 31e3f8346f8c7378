"""Pictures of a synthetic frame: colour-mapped depth, cuboid wireframes, the RGB | depth | cuboids strip."""

from __future__ import annotations

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid, palette_color

_EDGES = [(i, i ^ bit) for i in range(8) for bit in (1, 2, 4) if i < i ^ bit]  # corners differing in one sign
STRUCTURE = frozenset({"floor", "ceiling", "wall", "door_frame"})


def colorize_depth(depth_m: np.ndarray, range_m: tuple[float, float] | None = None) -> np.ndarray:
    """Depth (H, W) metres -> (H, W, 3) uint8 RGB (turbo colour map, near = blue); holes are black.

    ``range_m`` = (near, far) maps to the ends of the colour map; default: the 1st and 99th percentiles.
    """
    import cv2

    valid = depth_m > 0
    if range_m is None:
        range_m = tuple(np.percentile(depth_m[valid], [1, 99])) if valid.any() else (0.0, 1.0)
    near, far = range_m
    scaled = np.clip((depth_m - near) / max(far - near, 1e-6), 0.0, 1.0)
    img = cv2.applyColorMap((scaled * 255).astype(np.uint8), cv2.COLORMAP_TURBO)[..., ::-1].copy()
    img[~valid] = 0
    return img


def _clip_segment(a: np.ndarray, b: np.ndarray, near: float) -> tuple[np.ndarray, np.ndarray] | None:
    """The part of segment a-b (camera frame) in front of the plane z = near, or None."""
    if a[2] < near and b[2] < near:
        return None
    if a[2] < near:
        a = a + (b - a) * (near - a[2]) / (b[2] - a[2])
    elif b[2] < near:
        b = b + (a - b) * (near - b[2]) / (a[2] - b[2])
    return a, b


def draw_cuboids(rgb: np.ndarray, cuboids: list[Cuboid], camera: Camera, thickness: int = 2) -> np.ndarray:
    """Wireframes of cuboids (camera frame) over a copy of ``rgb`` (H, W, 3) uint8.

    Structural boxes (extras category floor / ceiling / wall / door_frame) are drawn thin and white, the
    others in the shared palette by their object id (or list index).
    """
    import cv2

    out = np.ascontiguousarray(rgb.copy())
    order = sorted(range(len(cuboids)), key=lambda k: cuboids[k].extras.get("category") not in STRUCTURE)
    for k in order:
        c = cuboids[k]
        structural = c.extras.get("category") in STRUCTURE
        color = (235, 235, 235) if structural else palette_color(int(c.extras.get("object", k)))
        corners = c.corners()
        for i, j in _EDGES:
            seg = _clip_segment(corners[i], corners[j], 0.05)
            if seg is None:
                continue
            uv, _ = camera.project(np.stack(seg))
            if not np.isfinite(uv).all() or np.abs(uv).max() > 1e5:
                continue
            p0, p1 = (tuple(int(round(x * 16)) for x in p) for p in uv)  # 4 fractional bits
            cv2.line(out, p0, p1, color, 1 if structural else thickness, cv2.LINE_AA, shift=4)
    return out


def figure(
    rgb: np.ndarray, depth_m: np.ndarray, cuboids: list[Cuboid], camera: Camera, scale: float = 1.0
) -> np.ndarray:
    """The strip RGB | depth | cuboid overlay as one (H', 3 W', 3) uint8 image, resized by ``scale``."""
    import cv2

    panels = [rgb, colorize_depth(depth_m), draw_cuboids(rgb, cuboids, camera)]
    if scale != 1.0:
        size = (int(round(camera.width * scale)), int(round(camera.height * scale)))
        panels = [cv2.resize(p, size, interpolation=cv2.INTER_AREA) for p in panels]
    gap = np.full((panels[0].shape[0], 4, 3), 255, np.uint8)
    return np.concatenate([panels[0], gap, panels[1], gap, panels[2]], axis=1)

"""Image outputs: cuboids drawn over the input image, a per-pixel label image, and a report panel.

Visibility is exact per pixel: every pixel's camera ray is intersected with every box (slab test in the
box's own frame) and the nearest hit wins, which gives the z-buffer, the label image (which cuboid is seen
at each pixel) and the face shading in one pass. Edges are sampled along their projection and drawn only
where no other surface is in front of them. Pixel (u, v) is the centre of the pixel in column u, row v,
as in :class:`cuboidcli.camera.Camera`. Images are RGB uint8 (H, W, 3) in memory; PNGs are written with
OpenCV, atomically.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid, palette_color
from cuboidcli.export.boxmesh import BOX_EDGES
from cuboidcli.io.atomic import atomic_write

#: Background colour (RGB) when there is neither an RGB image nor a depth map.
BLANK_RGB: tuple[int, int, int] = (32, 32, 32)
#: The longest side, in pixels, the written images of a larger frame are drawn at. A 12 MP photo drawn at
#: full size costs seconds and about a gigabyte (a float image to blend, a per-pixel z-buffer, a four-tile
#: panel four photos wide) for pictures no one views at that size; 1600 px shows the boxes as clearly.
MAX_IMAGE_SIDE = 1600
_NEAR_M = 0.01  # edges are clipped to z >= 1 cm in front of the camera


@dataclass
class RayCast:
    """Per-pixel result of casting the camera rays at the cuboids.

    ``depth_m`` (H, W) float64: z (metres) of the nearest cuboid surface, inf where no cuboid is hit.
    ``label`` (H, W) int32: index of that cuboid, -1 where none. ``shade`` (H, W) float32 in [0, 1]:
    |cos| of the angle between the ray and the normal of the side it hits (0 where none).
    """

    depth_m: np.ndarray
    label: np.ndarray
    shade: np.ndarray


def _check_image(name: str, image: np.ndarray, camera: Camera) -> None:
    if image.shape[:2] != (camera.height, camera.width):
        raise ValueError(
            f"{name} is {image.shape[1]}x{image.shape[0]} but the result's camera is "
            f"{camera.width}x{camera.height}; pass the image the result was fitted on"
        )


def raycast(camera: Camera, cuboids: list[Cuboid]) -> RayCast:
    """Intersect the ray of every pixel with every cuboid and keep the nearest hit (an exact z-buffer).

    The ray of pixel (u, v) is ``t * d`` with ``d = ((u - cx) / fx, (v - cy) / fy, 1)``, so the ray
    parameter t is the z-depth. In the box frame the ray is ``o + t * R^T d`` with ``o = -R^T c``; the slab
    test gives the entry t_near and exit t_far. A camera inside a box sees the box's inside (t_far).
    """
    from cuboidcli.geometry.raycast import raycast_boxes

    k = len(cuboids)
    centers = np.array([c.center for c in cuboids], dtype=np.float64).reshape(k, 3)
    half = np.array([c.half_size for c in cuboids], dtype=np.float64).reshape(k, 3)
    rots = np.array([c.rotation for c in cuboids], dtype=np.float64).reshape(k, 3, 3)
    depth, label, shade = raycast_boxes(
        float(camera.fx),
        float(camera.fy),
        float(camera.cx),
        float(camera.cy),
        int(camera.width),
        int(camera.height),
        centers,
        half,
        rots,
    )
    return RayCast(depth, label, shade)


def label_image(cast_or_label: RayCast | np.ndarray) -> np.ndarray:
    """Label PNG data (H, W): 0 = background, k + 1 = cuboid k; uint8 below 255 cuboids, else uint16."""
    label = cast_or_label.label if isinstance(cast_or_label, RayCast) else np.asarray(cast_or_label)
    dtype = np.uint8 if label.max(initial=-1) <= 254 else np.uint16
    return (label.astype(np.int64) + 1).astype(dtype)


def colorize_labels(label: np.ndarray) -> np.ndarray:
    """(H, W) labels (-1 background, k cuboid k) -> (H, W, 3) uint8 RGB, palette colours on black."""
    label = np.asarray(label)
    n = max(int(label.max(initial=-1)) + 1, 0)
    table = np.array([(0, 0, 0), *(palette_color(k) for k in range(n))], dtype=np.uint8)
    return table[label.astype(np.int64) + 1]


def colorize_depth(depth_m: np.ndarray) -> np.ndarray:
    """(H, W) depth in metres -> (H, W, 3) uint8 RGB (turbo, near = red, far = blue; missing = black).

    The colour range spans the 2nd to 98th percentile of the valid depths, so outliers do not flatten it.
    """
    import cv2

    valid = valid_depth(depth_m)
    out = np.zeros((*depth_m.shape, 3), dtype=np.uint8)
    if not valid.any():
        return out
    lo, hi = np.percentile(depth_m[valid], [2.0, 98.0])
    x = np.clip((depth_m - lo) / max(hi - lo, 1e-6), 0.0, 1.0)
    u8 = np.round(255.0 * (1.0 - x)).astype(np.uint8)
    rgb = cv2.cvtColor(cv2.applyColorMap(u8, cv2.COLORMAP_TURBO), cv2.COLOR_BGR2RGB)
    out[valid] = rgb[valid]
    return out


def _visible_runs(camera: Camera, cuboid: Cuboid, zmax: np.ndarray) -> list[np.ndarray]:
    """Pixel polylines (n, 2) of the visible parts of a cuboid's 12 edges.

    An edge sample is visible unless every cuboid surface in the 3x3 pixels around it is nearer by more
    than 1 % + 5 mm; ``zmax`` (H, W) is the 3x3 maximum of the z-buffer, so silhouettes never self-occlude.
    """
    runs = []
    corners = cuboid.corners()
    for i, j in BOX_EDGES:
        p0, p1 = corners[i], corners[j]
        if p0[2] < _NEAR_M and p1[2] < _NEAR_M:
            continue
        if p0[2] < _NEAR_M or p1[2] < _NEAR_M:  # clip the edge at the near plane
            s = (_NEAR_M - p0[2]) / (p1[2] - p0[2])
            q = p0 + s * (p1 - p0)
            p0, p1 = (q, p1) if p0[2] < _NEAR_M else (p0, q)
        (uv0, uv1), _ = camera.project(np.stack([p0, p1]))
        n = int(np.clip(np.ceil(np.linalg.norm(uv1 - uv0)), 1, 4000)) + 1
        pts = p0 + np.linspace(0.0, 1.0, n)[:, None] * (p1 - p0)
        uv, z = camera.project(pts)
        ui, vi = np.round(uv[:, 0]).astype(np.int64), np.round(uv[:, 1]).astype(np.int64)
        inside = (ui >= 0) & (ui < camera.width) & (vi >= 0) & (vi < camera.height)
        visible = np.ones(n, dtype=bool)
        visible[inside] = z[inside] <= zmax[vi[inside], ui[inside]] * 1.01 + 0.005
        # split into runs of consecutive visible samples
        edges = np.flatnonzero(np.diff(np.concatenate([[0], visible.astype(np.int8), [0]])))
        for a, b in zip(edges[0::2], edges[1::2], strict=True):
            if b - a >= 2:
                runs.append(uv[a:b])
    return runs


def draw_overlay(
    background: np.ndarray,
    camera: Camera,
    cuboids: list[Cuboid],
    cast: RayCast | None = None,
    alpha: float = 0.45,
    edge_px: int = 2,
    names: bool = True,
) -> np.ndarray:
    """Cuboids over ``background`` (H, W, 3) uint8 RGB: shaded semi-transparent faces and visible edges.

    Faces blend the cuboid's palette colour (darker on sides seen at a grazing angle) with weight
    ``alpha``; edges are ``edge_px`` wide, anti-aliased, hidden where another cuboid is in front. With
    ``names`` each cuboid's scene name (floor_00, wall_01, ...) is written at the middle of what is seen
    of it.
    """
    import cv2

    _check_image("the background image", background, camera)
    cast = raycast(camera, cuboids) if cast is None else cast
    # Only the pixels a cuboid covers change: they alone are blended in float32 (the same arithmetic as
    # over the whole image); the others keep their bytes, so no float copy of the whole image is made.
    src = np.asarray(background)
    out = src.copy(order="C") if src.dtype == np.uint8 else _to_uint8(src.astype(np.float32))
    if cuboids:
        colors = np.array([palette_color(k) for k in range(len(cuboids))], dtype=np.float32)
        m = cast.label >= 0
        face = colors[cast.label[m]] * (0.45 + 0.55 * cast.shade[m])[:, None]
        out[m] = _to_uint8((1.0 - alpha) * src[m].astype(np.float32) + alpha * face)
    if not cuboids or edge_px <= 0:
        return out
    zbuf = np.where(np.isfinite(cast.depth_m), cast.depth_m, 1e6).astype(np.float32)
    zmax = cv2.dilate(zbuf, np.ones((3, 3), np.uint8))
    shift = 4  # sub-pixel line positions, 1/16 px
    for k, cub in enumerate(cuboids):
        runs = _visible_runs(camera, cub, zmax)
        polys = [np.round(r * (1 << shift)).astype(np.int32).reshape(-1, 1, 2) for r in runs]
        if polys:
            cv2.polylines(
                out, polys, False, tuple(int(c) for c in palette_color(k)), edge_px, cv2.LINE_AA, shift
            )
    if names:
        _write_names(out, cuboids, cast.label)
    return out


def _to_uint8(values: np.ndarray) -> np.ndarray:
    return np.clip(np.round(values), 0, 255).astype(np.uint8)


def _write_names(img: np.ndarray, cuboids: list[Cuboid], label: np.ndarray) -> None:
    """Each cuboid's name at the median pixel of its visible part (none where it is not seen), white on a
    dark outline, sized to the image."""
    import cv2

    h, w = label.shape
    scale = max(0.35, min(h, w) / 900.0)
    thick = max(1, int(round(scale * 2)))
    step = max(1, min(h, w) // 240)  # a subsample finds the middle as well, at 12 MP too
    sub = label[::step, ::step]
    for k, cub in enumerate(cuboids):
        rows, cols = np.nonzero(sub == k)
        if rows.size < 20:
            continue
        text = cub.name(k)
        (tw, th), _ = cv2.getTextSize(text, cv2.FONT_HERSHEY_SIMPLEX, scale, thick)
        x = int(np.clip(np.median(cols) * step - tw / 2, 0, max(w - tw, 0)))
        y = int(np.clip(np.median(rows) * step + th / 2, th, h - 1))
        cv2.putText(img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, scale, (0, 0, 0), thick + 2, cv2.LINE_AA)
        cv2.putText(img, text, (x, y), cv2.FONT_HERSHEY_SIMPLEX, scale, (255, 255, 255), thick, cv2.LINE_AA)


def background_image(
    camera: Camera, rgb: np.ndarray | None = None, depth_m: np.ndarray | None = None
) -> np.ndarray:
    """The RGB image if given, else the colour-mapped depth, else a dark grey image; (H, W, 3) uint8."""
    if rgb is not None:
        _check_image("the RGB image", rgb, camera)
        return np.asarray(rgb, dtype=np.uint8)
    if depth_m is not None:
        _check_image("the depth map", depth_m, camera)
        return colorize_depth(depth_m)
    return np.full((camera.height, camera.width, 3), BLANK_RGB, dtype=np.uint8)


def make_panel(tiles: list[tuple[str, np.ndarray]], title_px: int = 28, gap_px: int = 4) -> np.ndarray:
    """Tiles (title, (H, W, 3) uint8 RGB) side by side with a title bar above each; all tiles share H."""
    import cv2

    h = tiles[0][1].shape[0]
    cols = []
    for i, (title, tile) in enumerate(tiles):
        if tile.shape[0] != h:
            raise ValueError("all panel tiles must have the same height")
        bar = np.full((title_px, tile.shape[1], 3), 24, dtype=np.uint8)
        cv2.putText(
            bar, title, (8, title_px - 9), cv2.FONT_HERSHEY_SIMPLEX, 0.6, (240, 240, 240), 1, cv2.LINE_AA
        )
        cols.append(np.concatenate([bar, tile], axis=0))
        if i + 1 < len(tiles):
            cols.append(np.full((h + title_px, gap_px, 3), 255, dtype=np.uint8))
    return np.concatenate(cols, axis=1)


def drawing_size(camera: Camera, max_side: int | None = MAX_IMAGE_SIDE) -> tuple[int, int]:
    """(width, height) the images of ``camera``'s frame are drawn at: its own size when its longer side
    is at most ``max_side`` (None: no bound), else shrunk to ``max_side`` on the longer side, keeping the
    aspect ratio."""
    w, h = int(camera.width), int(camera.height)
    if max_side is None or max(w, h) <= max_side:
        return w, h
    s = max_side / max(w, h)
    return max(1, int(round(w * s))), max(1, int(round(h * s)))


def shrink_inputs(
    camera: Camera,
    rgb: np.ndarray | None,
    depth_m: np.ndarray | None,
    max_side: int | None = MAX_IMAGE_SIDE,
) -> tuple[Camera, np.ndarray | None, np.ndarray | None]:
    """The camera, image and depth map of a frame at :func:`drawing_size`: unchanged when they fit, else
    the intrinsics scaled (pixel-centre convention), the image area-averaged and the depth map sampled at
    the nearest pixel (averaging would blend missing pixels, 0, into their neighbours' depth)."""
    import cv2

    w, h = drawing_size(camera, max_side)
    if (w, h) == (camera.width, camera.height):
        return camera, rgb, depth_m
    if rgb is not None:
        _check_image("the RGB image", rgb, camera)
        rgb = cv2.resize(np.asarray(rgb, dtype=np.uint8), (w, h), interpolation=cv2.INTER_AREA)
    if depth_m is not None:
        _check_image("the depth map", depth_m, camera)
        depth_m = np.asarray(depth_m, dtype=np.float32)
        depth_m = cv2.resize(depth_m, (w, h), interpolation=cv2.INTER_NEAREST_EXACT)
    return camera.scaled(w / camera.width, h / camera.height), rgb, depth_m


def render_images(
    camera: Camera,
    cuboids: list[Cuboid],
    rgb: np.ndarray | None = None,
    depth_m: np.ndarray | None = None,
    max_side: int | None = None,
) -> dict[str, np.ndarray]:
    """All image outputs in memory: ``overlay``, ``labels`` (raw, 0 = background), ``labels_color``,
    ``panel``.

    The panel is image | depth | cuboids | labels, leaving out the inputs that are not given. With
    ``max_side`` a frame larger than that on its longer side is drawn at :func:`drawing_size` (every
    image but the panel then has that size; the labels are those of its pixels), and the panel's tiles are
    at most half that on their longer side, as the panel is up to four of them wide; None: all at the
    camera's size.
    """
    camera, rgb, depth_m = shrink_inputs(camera, rgb, depth_m, max_side)
    cast = raycast(camera, cuboids)
    background = background_image(camera, rgb, depth_m)
    overlay = draw_overlay(background, camera, cuboids, cast)
    labels_color = colorize_labels(cast.label)
    tile_size = drawing_size(camera, None if max_side is None else max(1, max_side // 2))
    tiles = []
    if rgb is not None:
        tiles.append(("image", _tile(background, tile_size)))
    if depth_m is not None:
        # the depth's own colours at the tile's pixels: averaging would blend holes into them
        tiles.append(("depth", colorize_depth(_tile(depth_m, tile_size, nearest=True))))
    tiles += [
        (f"cuboids ({len(cuboids)})", _tile(overlay, tile_size)),
        ("labels", _tile(labels_color, tile_size, nearest=True)),
    ]
    return {
        "overlay": overlay,
        "labels": label_image(cast),
        "labels_color": labels_color,
        "panel": make_panel(tiles),
    }


def _tile(image: np.ndarray, size: tuple[int, int], nearest: bool = False) -> np.ndarray:
    """``image`` at ``size`` (width, height): area-averaged, or the nearest pixel for images whose values
    are codes (labels, depths) that must not be mixed."""
    import cv2

    if image.shape[1::-1] == size:
        return image
    return cv2.resize(image, size, interpolation=cv2.INTER_NEAREST_EXACT if nearest else cv2.INTER_AREA)


def write_png(path: str | os.PathLike, image: np.ndarray) -> Path:
    """Write (H, W, 3) uint8 RGB or (H, W) uint8/uint16 grey as PNG, atomically. Returns ``path``."""
    import cv2

    data = cv2.cvtColor(image, cv2.COLOR_RGB2BGR) if image.ndim == 3 else image

    def _write(tmp: Path) -> None:
        if not cv2.imwrite(str(tmp), data):
            raise OSError(f"could not write PNG {path}")

    return atomic_write(path, _write)

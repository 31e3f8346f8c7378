"""Colour images: procedural textures (wood, fabric, paint, planks, tiles, carpet, foliage) and Lambertian
shading from a few point lights, the first of which casts shadows.

Textures live in each surface's own frame (a box's axes, a clutter object's frame), so they move with the
object. Fine patterns fade to their mean colour once a pixel covers more than a fraction of their period,
which keeps distant wood grain or weave from turning into aliasing noise.
"""

from __future__ import annotations

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.synth.mesh import Soup
from cuboidcli.synth.rays import pixel_directions
from cuboidcli.synth.render import Hits, RayCaster
from cuboidcli.synth.world import World

KINDS = ("plain", "paint", "wood", "fabric", "planks", "tiles", "carpet", "leaf")
BACKGROUND = np.array([0.02, 0.02, 0.025])
"""Linear colour of pixels that see nothing (beyond open sides of the room)."""
_TANGENT_AXES = np.array([[1, 2], [2, 0], [0, 1]])


def _hash(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """A deterministic pseudo-random value in [0, 1) per integer cell (a, b) (float64 inside: the
    large multiplier needs the precision), returned as float32."""
    x = np.sin(a.astype(np.float64) * 12.9898 + np.asarray(b, np.float64) * 78.233) * 43758.5453
    return (x - np.floor(x)).astype(np.float32)


def _fade(period_m: np.ndarray | float, pixel_m: np.ndarray) -> np.ndarray:
    """1 when a pattern of this period spans >= 6 pixels, 0 at <= 2 pixels (then show its mean)."""
    return np.clip((period_m / np.maximum(pixel_m, 1e-9) - 2.0) / 4.0, 0.0, 1.0)


def _wave(x: np.ndarray, period: np.ndarray | float, phase: np.ndarray | float) -> np.ndarray:
    return np.sin(np.float32(2.0 * np.pi) * x / period + phase)


def _texture(kind: str, s, t, rgb, rgb2, scale, phase, pixel_m, face) -> np.ndarray:
    """Albedo (N, 3) of one texture kind at surface coordinates s (along the grain) and t, metres."""
    p = [phase[:, k] for k in range(4)]
    if kind == "paint":
        mottle = 0.04 * _wave(s, scale, p[0]) * _wave(t, 1.37 * scale, p[1]) + 0.02 * _wave(
            s + t, 0.31 * scale, p[2]
        )
        return rgb * (1.0 + mottle)[:, None]
    if kind in ("wood", "planks"):
        grain_period = scale if kind == "wood" else np.full_like(scale, 0.012)
        warp = 0.35 * _wave(s, 9.0 * grain_period, p[0]) + 0.15 * _wave(s, 23.0 * grain_period, p[2])
        g = (0.5 + 0.5 * np.sin(2.0 * np.pi * (t / grain_period + warp) + p[1])) ** 4
        f = _fade(grain_period, pixel_m)
        g = f * g + (1.0 - f) * (35.0 / 128.0)  # mean of the fourth power of a raised sine
        col = rgb + (rgb2 - rgb) * (0.8 * g)[:, None]
        if kind == "planks":  # boards of width `scale` across t, each with its own tint and a dark seam
            u = t / scale + p[3]
            board = np.floor(u)
            col = col * (0.85 + 0.3 * _hash(board, p[3]))[:, None]
            seam = np.minimum(u - board, board + 1.0 - u) * scale < np.maximum(0.002, 0.5 * pixel_m)
            weight = np.clip(0.004 / np.maximum(pixel_m, 1e-9), 0.0, 1.0) * seam
            col = col * (1.0 - 0.5 * weight)[:, None]
        return col
    if kind == "fabric":
        weave = 0.5 + 0.25 * (_wave(s, scale, p[0]) + _wave(t, scale, p[1]))
        f = _fade(scale, pixel_m)
        w = f * weave + (1.0 - f) * 0.5
        mottle = 1.0 + 0.06 * _wave(s, 0.23, p[2]) * _wave(t, 0.31, p[3])
        return (rgb + (rgb2 - rgb) * (0.6 * w)[:, None]) * mottle[:, None]
    if kind == "tiles":
        us, ut = s / scale + p[0], t / scale + p[1]
        cs, ct = np.floor(us), np.floor(ut)
        col = rgb * (0.93 + 0.1 * _hash(cs, ct))[:, None]
        edge = np.minimum(np.minimum(us - cs, cs + 1 - us), np.minimum(ut - ct, ct + 1 - ut)) * scale
        grout = edge < np.maximum(0.003, 0.5 * pixel_m)
        weight = np.clip(0.006 / np.maximum(pixel_m, 1e-9), 0.0, 1.0) * grout
        return col + (rgb2 - col) * weight[:, None]
    if kind == "carpet":
        cell = 0.004
        fine = _hash(np.floor(s / cell), np.floor(t / cell)) - 0.5
        f = _fade(cell, pixel_m)
        mottle = 0.08 * _wave(s, 0.41, p[0]) * _wave(t, 0.53, p[1])
        return rgb * (1.0 + 0.25 * f * fine + mottle)[:, None]
    if kind == "leaf":  # every facet of the foliage its own shade of green
        return rgb * (0.6 + 0.7 * _hash(face.astype(np.float64), p[0]))[:, None]
    return rgb


def surface_coordinates(soup: Soup) -> tuple[np.ndarray, np.ndarray]:
    """Per face, the affine map from a world point to texture coordinates (s, t), metres.

    Returns ``coef`` (F, 2, 3) and ``offset`` (F, 2) with (s, t) = coef @ p - offset. A face's coordinates
    are its frame's two axes most nearly parallel to the face; s runs along the longer side of a box
    face (the grain of wood), t across it.
    """
    v = soup.vertices[soup.faces]
    normal = np.cross(v[:, 1] - v[:, 0], v[:, 2] - v[:, 0])
    rot = soup.frame_rotation[soup.frame]  # (F, 3, 3)
    half = soup.frame_half[soup.frame]
    axis = np.abs(np.einsum("fk,fkc->fc", normal, rot)).argmax(1)
    ta = _TANGENT_AXES[axis]
    rows = np.arange(len(axis))
    swap = half[rows, ta[:, 0]] < half[rows, ta[:, 1]]
    ia = np.where(swap, ta[:, 1], ta[:, 0])
    ib = np.where(swap, ta[:, 0], ta[:, 1])
    coef = np.stack([rot[rows, :, ia], rot[rows, :, ib]], 1)  # the chosen columns of each frame
    offset = np.einsum("fjk,fk->fj", coef, soup.frame_origin[soup.frame])
    return coef, offset


def albedo(
    points_w: np.ndarray,
    face: np.ndarray,
    soup: Soup,
    world: World,
    pixel_m: np.ndarray,
    coords: tuple[np.ndarray, np.ndarray] | None = None,
) -> np.ndarray:
    """Linear albedo (N, 3) of N surface points (N, 3), world frame, lying on faces (N,) of ``soup``.

    ``pixel_m`` (N,) is the size of a pixel's footprint on the surface, metres (for fading fine patterns);
    ``coords`` is :func:`surface_coordinates` of the soup (computed when not given).
    """
    coef, offset = coords if coords is not None else surface_coordinates(soup)
    st = (np.einsum("nk,njk->nj", points_w, coef[face]) - offset[face]).astype(np.float32)
    s, t = st[:, 0], st[:, 1]
    mats = world.materials
    mat = soup.material[face]
    kind_of = np.array([KINDS.index(m.kind) for m in mats])[mat]
    # textures are computed in float32: plenty for sub-millimetre patterns within a room, and faster
    rgb_all = np.stack([m.rgb for m in mats]).astype(np.float32)
    rgb2_all = np.stack([m.rgb2 for m in mats]).astype(np.float32)
    scale_all = np.array([m.scale_m for m in mats], np.float32)
    phase_all = np.stack([m.phase for m in mats]).astype(np.float32)
    out = np.empty((len(face), 3), np.float32)
    for k, kind in enumerate(KINDS):
        sel = np.flatnonzero(kind_of == k)
        if len(sel):
            m = mat[sel]
            out[sel] = _texture(
                kind,
                s[sel],
                t[sel],
                rgb_all[m],
                rgb2_all[m],
                scale_all[m],
                phase_all[m],
                pixel_m[sel],
                face[sel],
            )
    return np.clip(out, 0.0, 1.0)


def shade(
    hits: Hits,
    camera: Camera,
    rotation: np.ndarray,
    origin: np.ndarray,
    soup: Soup,
    world: World,
    caster: RayCaster | None,
    rng: np.random.Generator,
    noise_std: float = 0.01,
) -> np.ndarray:
    """The RGB image (H, W, 3) uint8 of a rendered view.

    ``rotation`` (3, 3) / ``origin`` (3,) are the camera-to-world pose used for ``hits``; ``caster`` (the
    world's ray caster) adds the first light's shadows when given; ``noise_std`` is the sensor noise in
    [0, 1] units of the encoded image.
    """
    h, w = hits.depth_m.shape
    idx = np.flatnonzero(hits.hit.ravel())
    face = hits.face.ravel()[idx]
    z = hits.depth_m.ravel()[idx].astype(np.float64)
    p_w = np.einsum("nk,ck->nc", pixel_directions(camera).reshape(-1, 3)[idx] * z[:, None], rotation) + origin
    n_w = np.einsum("nk,ck->nc", hits.normal.reshape(-1, 3)[idx].astype(np.float64), rotation)
    base = albedo(p_w, face, soup, world, (z / camera.fx).astype(np.float32))
    # sky-like ambient light: a little brighter on upward-facing surfaces
    irradiance = 0.22 * (0.8 + 0.2 * n_w[:, 2])
    for k, (pos, power) in enumerate(world.lights):
        to_light = pos - p_w
        dist2 = np.einsum("nk,nk->n", to_light, to_light)
        dist = np.sqrt(dist2)
        cos = np.clip(np.einsum("nk,nk->n", n_w, to_light) / dist, 0.0, None)
        # ceiling fixtures shine mostly downwards: little light reaches the ceiling around them
        down = np.clip(to_light[:, 2] / dist, 0.0, 1.0)
        e = power * cos * (0.15 + 0.85 * down) / np.maximum(dist2, 0.25)
        if k == 0 and caster is not None:
            lit = cos > 0
            start = p_w[lit] + 2e-3 * n_w[lit]  # lift off the surface so it does not shadow itself
            blocked = caster.occluded(start, pos - start)
            e[np.flatnonzero(lit)[blocked]] = 0.0
        irradiance = irradiance + e
    lin = base * irradiance[:, None].astype(np.float32)
    # auto exposure: the 97th percentile of luminance (on a fixed subsample, for speed) maps to 0.9
    lum = np.einsum("nc,c->n", lin[::7], np.array([0.2126, 0.7152, 0.0722], np.float32))
    gain = 0.9 / max(float(np.percentile(lum, 97)), 1e-6) if len(lum) else 1.0
    img = np.empty((h * w, 3), np.float32)
    img[:] = BACKGROUND
    img[idx] = lin * np.float32(gain)
    # gamma encoding through a lookup table: linear [0, 1] in 4096 steps -> sRGB-like [0, 255]
    lut = (np.linspace(0.0, 1.0, 4096) ** (1.0 / 2.2) * 255.0).astype(np.float32)
    srgb = lut[(np.clip(img, 0.0, 1.0) * 4095.0 + 0.5).astype(np.int32)]
    if noise_std > 0:
        srgb += rng.standard_normal(srgb.shape, dtype=np.float32) * np.float32(255.0 * noise_std)
    return np.clip(np.rint(srgb), 0, 255).astype(np.uint8).reshape(h, w, 3)

"""Random materials for each kind of surface: wall paint, floor, wood, fabric, metal, foliage...

Colours are linear albedos in [0, 1], drawn in HSV around plausible values for the surface.
"""

from __future__ import annotations

import colorsys

import numpy as np

from cuboidcli.synth.world import Material


def _hsv(rng: np.random.Generator, h, s, v) -> np.ndarray:
    """A linear RGB albedo from hue/saturation/value ranges (each a (lo, hi) pair)."""
    rgb = colorsys.hsv_to_rgb(rng.uniform(*h) % 1.0, rng.uniform(*s), rng.uniform(*v))
    return np.asarray(rgb) ** 2.2  # the ranges are perceptual (sRGB-like); shading works in linear light


def _make(kind: str, rgb: np.ndarray, rgb2: np.ndarray, scale_m: float, rng: np.random.Generator) -> Material:
    return Material(kind, rgb, rgb2, scale_m, rng.uniform(0.0, 2.0 * np.pi, 4))


def sample(palette: str, rng: np.random.Generator) -> Material:
    """A material from a named palette (see :data:`PALETTES`)."""
    if palette == "wall":
        c = _hsv(rng, (0.0, 1.0), (0.02, 0.25), (0.7, 0.95))
        return _make("paint", c, c, rng.uniform(0.6, 1.5), rng)
    if palette == "ceiling":
        c = _hsv(rng, (0.08, 0.15), (0.0, 0.05), (0.88, 0.96))
        return _make("paint", c, c, 1.0, rng)
    if palette == "floor":
        kind = rng.choice(["planks", "tiles", "carpet"], p=[0.45, 0.3, 0.25])
        if kind == "planks":
            c = _hsv(rng, (0.05, 0.1), (0.35, 0.7), (0.35, 0.75))
            return _make("planks", c, c * rng.uniform(0.55, 0.75), rng.uniform(0.1, 0.2), rng)
        if kind == "tiles":
            c = _hsv(rng, (0.0, 1.0), (0.0, 0.15), (0.55, 0.9))
            return _make("tiles", c, c * 0.5, rng.uniform(0.3, 0.6), rng)
        return _make("carpet", _hsv(rng, (0.0, 1.0), (0.1, 0.5), (0.25, 0.6)), np.zeros(3), 0.004, rng)
    if palette == "wood":
        c = _hsv(rng, (0.05, 0.11), (0.35, 0.75), (0.3, 0.85))
        return _make("wood", c, c * rng.uniform(0.55, 0.8), rng.uniform(0.008, 0.02), rng)
    if palette == "painted":
        if rng.random() < 0.6:
            c = _hsv(rng, (0.0, 1.0), (0.0, 0.08), (0.15, 0.95))
        else:
            c = _hsv(rng, (0.0, 1.0), (0.2, 0.6), (0.35, 0.85))
        return _make("paint", c, c, rng.uniform(0.3, 1.0), rng)
    if palette == "fabric":
        c = _hsv(rng, (0.0, 1.0), (0.1, 0.6), (0.2, 0.85))
        return _make("fabric", c, c * 0.8, rng.uniform(0.003, 0.006), rng)
    if palette == "metal":
        c = _hsv(rng, (0.55, 0.65), (0.0, 0.1), (0.2, 0.75))
        return _make("plain", c, c, 1.0, rng)
    if palette == "cardboard":
        c = _hsv(rng, (0.07, 0.1), (0.4, 0.6), (0.5, 0.75))
        return _make("paint", c, c, 0.3, rng)
    if palette == "vivid":
        c = _hsv(rng, (0.0, 1.0), (0.5, 0.9), (0.4, 0.95))
        return _make("plain", c, c, 1.0, rng)
    if palette == "dark":
        c = _hsv(rng, (0.0, 1.0), (0.0, 0.1), (0.05, 0.15))
        return _make("plain", c, c, 1.0, rng)
    if palette == "leaf":
        c = _hsv(rng, (0.22, 0.38), (0.5, 0.8), (0.25, 0.55))
        return _make("leaf", c, c * 0.6, 1.0, rng)
    if palette == "terracotta":
        c = _hsv(rng, (0.02, 0.07), (0.5, 0.75), (0.45, 0.7))
        return _make("paint", c, c, 0.3, rng)
    if palette == "skin":
        c = _hsv(rng, (0.04, 0.09), (0.25, 0.6), (0.35, 0.95))
        return _make("plain", c, c, 1.0, rng)
    raise ValueError(f"unknown palette {palette!r}")


#: Palette choices per (category, part role), with probabilities; "*" is the fallback category.
PALETTES: dict[str, dict[str, tuple[tuple[str, ...], tuple[float, ...]]]] = {
    "*": {
        "main": (("wood", "painted"), (0.6, 0.4)),
        "accent": (("wood", "painted"), (0.5, 0.5)),
        "soft": (("fabric",), (1.0,)),
        "metal": (("metal",), (1.0,)),
        "leaf": (("leaf",), (1.0,)),
        "skin": (("skin",), (1.0,)),
    },
    "cabinet": {"main": (("wood", "painted"), (0.45, 0.55))},
    "wall_cupboard": {"main": (("wood", "painted"), (0.4, 0.6))},
    "sofa": {"accent": (("fabric", "dark"), (0.5, 0.5))},
    "box": {"main": (("cardboard", "painted", "vivid"), (0.5, 0.3, 0.2))},
    "book": {"main": (("vivid", "painted"), (0.7, 0.3))},
    "monitor": {"accent": (("dark",), (1.0,))},
    "bin": {"main": (("vivid", "metal", "dark"), (0.5, 0.3, 0.2))},
    "ball": {"main": (("vivid",), (1.0,))},
    "cone": {"main": (("vivid",), (1.0,))},
    "vase": {"main": (("vivid", "painted", "terracotta"), (0.4, 0.3, 0.3))},
    "plant": {"accent": (("terracotta", "painted"), (0.6, 0.4))},
    "lamp": {"soft": (("fabric", "painted"), (0.6, 0.4))},
}


def palette_for(category: str, role: str, rng: np.random.Generator) -> str:
    names, probs = PALETTES.get(category, {}).get(role) or PALETTES["*"][role]
    return str(rng.choice(names, p=probs))

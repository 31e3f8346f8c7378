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


#: A material of one HSV colour: (kind, hue, saturation and value ranges, factor from the main colour to the
#: secondary one, scale in metres). A factor or scale given as a (lo, hi) pair is drawn uniformly, in that
#: order, after the colour.
_Recipe = tuple[str, tuple, tuple, tuple, float | tuple, float | tuple]

#: The palettes of :func:`sample` that are a single recipe ("floor" and "painted" choose among recipes).
_RECIPES: dict[str, _Recipe] = {
    "wall": ("paint", (0.0, 1.0), (0.02, 0.25), (0.7, 0.95), 1.0, (0.6, 1.5)),
    "ceiling": ("paint", (0.08, 0.15), (0.0, 0.05), (0.88, 0.96), 1.0, 1.0),
    "wood": ("wood", (0.05, 0.11), (0.35, 0.75), (0.3, 0.85), (0.55, 0.8), (0.008, 0.02)),
    "fabric": ("fabric", (0.0, 1.0), (0.1, 0.6), (0.2, 0.85), 0.8, (0.003, 0.006)),
    "metal": ("plain", (0.55, 0.65), (0.0, 0.1), (0.2, 0.75), 1.0, 1.0),
    "cardboard": ("paint", (0.07, 0.1), (0.4, 0.6), (0.5, 0.75), 1.0, 0.3),
    "vivid": ("plain", (0.0, 1.0), (0.5, 0.9), (0.4, 0.95), 1.0, 1.0),
    "dark": ("plain", (0.0, 1.0), (0.0, 0.1), (0.05, 0.15), 1.0, 1.0),
    "leaf": ("leaf", (0.22, 0.38), (0.5, 0.8), (0.25, 0.55), 0.6, 1.0),
    "terracotta": ("paint", (0.02, 0.07), (0.5, 0.75), (0.45, 0.7), 1.0, 0.3),
    "skin": ("plain", (0.04, 0.09), (0.25, 0.6), (0.35, 0.95), 1.0, 1.0),
}

#: Floor recipes, chosen with probabilities 0.45, 0.3, 0.25 (a carpet has no secondary colour).
_FLOORS: dict[str, _Recipe] = {
    "planks": ("planks", (0.05, 0.1), (0.35, 0.7), (0.35, 0.75), (0.55, 0.75), (0.1, 0.2)),
    "tiles": ("tiles", (0.0, 1.0), (0.0, 0.15), (0.55, 0.9), 0.5, (0.3, 0.6)),
    "carpet": ("carpet", (0.0, 1.0), (0.1, 0.5), (0.25, 0.6), 0.0, 0.004),
}

#: "painted": mostly near-grey (probability 0.6), else a saturated colour.
_PAINTED: tuple[_Recipe, _Recipe] = (
    ("paint", (0.0, 1.0), (0.0, 0.08), (0.15, 0.95), 1.0, (0.3, 1.0)),
    ("paint", (0.0, 1.0), (0.2, 0.6), (0.35, 0.85), 1.0, (0.3, 1.0)),
)


def _value(rng: np.random.Generator, x) -> float:
    """``x``, or a uniform draw from it when it is a (lo, hi) pair."""
    return rng.uniform(*x) if isinstance(x, tuple) else x


def _from_recipe(recipe: _Recipe, rng: np.random.Generator) -> Material:
    kind, h, s, v, factor, scale = recipe
    c = _hsv(rng, h, s, v)
    return _make(kind, c, c * _value(rng, factor), _value(rng, scale), rng)


def sample(palette: str, rng: np.random.Generator) -> Material:
    """A material from a named palette (see :data:`PALETTES`)."""
    if palette == "floor":
        recipe = _FLOORS[rng.choice(["planks", "tiles", "carpet"], p=[0.45, 0.3, 0.25])]
    elif palette == "painted":
        recipe = _PAINTED[0] if rng.random() < 0.6 else _PAINTED[1]
    elif palette in _RECIPES:
        recipe = _RECIPES[palette]
    else:
        raise ValueError(f"unknown palette {palette!r}")
    return _from_recipe(recipe, rng)


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

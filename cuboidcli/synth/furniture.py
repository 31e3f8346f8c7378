"""Furniture as box assemblies with random sizes in plausible real ranges (metres).

Each generator builds one piece in its own frame: the origin on the floor under the footprint centre,
x along the width, y along the depth with +y the front (the side one uses; the back goes against a wall),
z up. Parts are axis-aligned in that frame; placement later adds the yaw and the position.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field

import numpy as np

#: Part roles; the scene gives each role of an object one material.
MAIN, ACCENT, SOFT, METAL = "main", "accent", "soft", "metal"


@dataclass
class LocalBox:
    """An axis-aligned part in the object frame, from corner ``lo`` (3,) to corner ``hi`` (3,)."""

    name: str
    lo: np.ndarray
    hi: np.ndarray
    role: str = MAIN


@dataclass
class Surface:
    """A horizontal support in the object frame: height ``z`` and the xy rectangle [lo, hi] (2,) each.
    ``clearance_m`` is the free height above it (inf when nothing is above)."""

    z: float
    lo: np.ndarray
    hi: np.ndarray
    clearance_m: float = float("inf")


@dataclass
class Assembly:
    """A piece of furniture: its category, parts and support surfaces."""

    category: str
    parts: list[LocalBox] = field(default_factory=list)
    surfaces: list[Surface] = field(default_factory=list)

    def box(self, name: str, lo, hi, role: str = MAIN) -> None:
        self.parts.append(LocalBox(name, np.asarray(lo, float), np.asarray(hi, float), role))

    def surface(self, z: float, lo, hi, clearance_m: float = float("inf"), margin: float = 0.03) -> None:
        lo, hi = np.asarray(lo, float) + margin, np.asarray(hi, float) - margin
        if (hi > lo).all():
            self.surfaces.append(Surface(z, lo, hi, clearance_m))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners (3,), (3,) of the axis-aligned box around all parts."""
        return np.min([p.lo for p in self.parts], 0), np.max([p.hi for p in self.parts], 0)


def _legs(a: Assembly, hx: float, hy: float, top_z: float, leg: float, inset: float, role: str) -> None:
    for sx in (-1, 1):
        for sy in (-1, 1):
            x0, y0 = sx * (hx - inset), sy * (hy - inset)
            a.box(
                "leg",
                [min(x0, x0 - sx * leg), min(y0, y0 - sy * leg), 0.0],
                [max(x0, x0 - sx * leg), max(y0, y0 - sy * leg), top_z],
                role,
            )


def _slab_on_legs(
    a: Assembly,
    name: str,
    hx: float,
    hy: float,
    top: float,
    t: float,
    leg: float,
    inset: float,
    rng: np.random.Generator,
) -> None:
    """A slab ``name`` (2 hx x 2 hy, ``t`` thick, its top at ``top``) on four legs of width ``leg``, set in
    ``inset`` from the corners; the legs' role (main or metal) is drawn from ``rng``."""
    a.box(name, [-hx, -hy, top - t], [hx, hy, top])
    _legs(a, hx, hy, top - t, leg, inset, rng.choice([MAIN, METAL]))


def table(rng: np.random.Generator) -> Assembly:
    """Dining or coffee table: a top on four legs."""
    a = Assembly("table")
    coffee = rng.random() < 0.25
    length = rng.uniform(0.8, 1.3) if coffee else rng.uniform(0.8, 1.8)
    width = min(rng.uniform(0.5, 1.0), length)
    height = rng.uniform(0.38, 0.5) if coffee else rng.uniform(0.70, 0.78)
    t = rng.uniform(0.025, 0.05)
    hx, hy = length / 2, width / 2
    _slab_on_legs(a, "top", hx, hy, height, t, rng.uniform(0.04, 0.08), rng.uniform(0.0, 0.08), rng)
    a.surface(height, [-hx, -hy], [hx, hy])
    return a


def desk(rng: np.random.Generator) -> Assembly:
    """Desk: a top on a drawer pedestal and a side panel (or two legs), often with a modesty panel."""
    a = Assembly("desk")
    length, depth, height = rng.uniform(1.0, 1.6), rng.uniform(0.5, 0.8), rng.uniform(0.72, 0.76)
    t, hx, hy = rng.uniform(0.025, 0.04), length / 2, depth / 2
    a.box("top", [-hx, -hy, height - t], [hx, hy, height])
    side = rng.choice([-1.0, 1.0])
    ped = rng.uniform(0.35, 0.45)
    xs = sorted([side * hx, side * (hx - ped)])
    a.box("pedestal", [xs[0], -hy + 0.02, 0.0], [xs[1], hy - 0.02, height - t], ACCENT)
    if rng.random() < 0.5:
        pt = rng.uniform(0.02, 0.04)
        xs = sorted([-side * hx, -side * (hx - pt)])
        a.box("panel", [xs[0], -hy, 0.0], [xs[1], hy, height - t])
    else:
        leg = rng.uniform(0.04, 0.06)
        for sy in (-1, 1):
            x0, y0 = -side * hx, sy * (hy - 0.02)
            a.box(
                "leg",
                [min(x0, x0 + side * leg), min(y0, y0 - sy * leg), 0.0],
                [max(x0, x0 + side * leg), max(y0, y0 - sy * leg), height - t],
                METAL,
            )
    if rng.random() < 0.6:
        a.box(
            "modesty panel",
            [-hx + ped, -hy, height - t - rng.uniform(0.25, 0.4)],
            [hx - ped, -hy + 0.02, height - t],
        )
    a.surface(height, [-hx, -hy], [hx, hy])
    return a


def bed(rng: np.random.Generator) -> Assembly:
    """Bed: base, mattress, headboard (against the wall, at -y), sometimes a footboard and pillows."""
    a = Assembly("bed")
    width, length = rng.choice([rng.uniform(0.9, 1.0), rng.uniform(1.4, 1.8)]), rng.uniform(1.95, 2.1)
    hx, hy = width / 2, length / 2
    base_h, mat_h, head_t = rng.uniform(0.2, 0.35), rng.uniform(0.15, 0.25), rng.uniform(0.05, 0.1)
    foot_t = rng.uniform(0.04, 0.06) if rng.random() < 0.3 else 0.0
    a.box("headboard", [-hx, -hy, 0.0], [hx, -hy + head_t, rng.uniform(0.8, 1.2)])
    if foot_t:
        a.box("footboard", [-hx, hy - foot_t, 0.0], [hx, hy, base_h + mat_h + rng.uniform(0.0, 0.2)])
    a.box("base", [-hx, -hy + head_t, 0.0], [hx, hy - foot_t, base_h], ACCENT)
    inset = rng.uniform(0.0, 0.04)
    top = base_h + mat_h
    a.box("mattress", [-hx + inset, -hy + head_t, base_h], [hx - inset, hy - foot_t - inset, top], SOFT)
    n_pillows = int(rng.integers(0, 3)) if width > 1.2 else int(rng.integers(0, 2))
    pw = min(0.6, (width - 0.1) / max(n_pillows, 1))
    for k in range(n_pillows):
        x0 = -hx + 0.05 + k * (width - 0.1) / n_pillows
        a.box(
            "pillow", [x0, -hy + head_t + 0.03, top], [x0 + pw - 0.02, -hy + head_t + 0.38, top + 0.1], SOFT
        )
    return a


def cabinet(rng: np.random.Generator) -> Assembly:
    """Cabinet, chest of drawers or wardrobe: a body on a recessed plinth, sometimes an overhanging top."""
    a = Assembly("cabinet")
    width, depth, height = rng.uniform(0.4, 1.2), rng.uniform(0.35, 0.6), rng.uniform(0.5, 2.0)
    hx, hy, plinth = width / 2, depth / 2, rng.uniform(0.05, 0.1)
    a.box("plinth", [-hx + 0.03, -hy, 0.0], [hx - 0.03, hy - 0.04, plinth], ACCENT)
    a.box("body", [-hx, -hy, plinth], [hx, hy, height])
    if rng.random() < 0.4 and height < 1.3:
        over = rng.uniform(0.01, 0.03)
        a.box("top", [-hx - over, -hy, height], [hx + over, hy + over, height + 0.03], ACCENT)
        height += 0.03
    if height < 1.6:
        a.surface(height, [-hx, -hy], [hx, hy])
    return a


def shelf(rng: np.random.Generator) -> Assembly:
    """Open shelf with compartments: sides, bottom, top, back, inner boards, sometimes a divider."""
    a = Assembly("shelf")
    width, depth, height = rng.uniform(0.6, 1.2), rng.uniform(0.25, 0.4), rng.uniform(0.8, 2.0)
    t, hx, hy = rng.uniform(0.018, 0.03), width / 2, depth / 2
    a.box("side", [-hx, -hy, 0.0], [-hx + t, hy, height])
    a.box("side", [hx - t, -hy, 0.0], [hx, hy, height])
    a.box("back", [-hx + t, -hy, 0.0], [hx - t, -hy + 0.01, height], ACCENT)
    n_inner = max(1, int(round((height - 0.1) / rng.uniform(0.3, 0.4))) - 1)
    levels = np.linspace(0.05, height - t, n_inner + 2)
    for z in levels:
        a.box("board", [-hx + t, -hy + 0.01, z], [hx - t, hy, z + t])
    a.box("plinth", [-hx + t, hy - 0.02, 0.0], [hx - t, hy, 0.05], ACCENT)
    divider = rng.random() < 0.4
    if divider:
        a.box("divider", [-t / 2, -hy + 0.01, levels[0] + t], [t / 2, hy, levels[1]])
    for k, (z0, z1) in enumerate(zip(levels[:-1], levels[1:], strict=True)):
        clearance = z1 - z0 - t
        if k == 0 and divider:
            a.surface(z0 + t, [-hx + t, -hy + 0.01], [-t / 2, hy], clearance, margin=0.01)
            a.surface(z0 + t, [t / 2, -hy + 0.01], [hx - t, hy], clearance, margin=0.01)
        else:
            a.surface(z0 + t, [-hx + t, -hy + 0.01], [hx - t, hy], clearance, margin=0.01)
    if height < 1.6:
        a.surface(height, [-hx, -hy], [hx, hy])
    return a


def sofa(rng: np.random.Generator) -> Assembly:
    """Sofa: base and seat cushion between two arms, a back rest behind (at -y)."""
    a = Assembly("sofa")
    width, depth = rng.uniform(1.5, 2.4), rng.uniform(0.8, 1.0)
    hx, hy = width / 2, depth / 2
    seat, cushion, arm_w = rng.uniform(0.4, 0.46), rng.uniform(0.1, 0.15), rng.uniform(0.12, 0.25)
    arm_h, back_t, back_h = rng.uniform(0.55, 0.68), rng.uniform(0.15, 0.25), rng.uniform(0.75, 0.95)
    for sx in (-1, 1):
        xs = sorted([sx * hx, sx * (hx - arm_w)])
        a.box("arm", [xs[0], -hy, 0.0], [xs[1], hy, arm_h], SOFT)
    a.box("back", [-hx + arm_w, -hy, 0.0], [hx - arm_w, -hy + back_t, back_h], SOFT)
    a.box("base", [-hx + arm_w, -hy + back_t, 0.0], [hx - arm_w, hy, seat - cushion], ACCENT)
    a.box("cushion", [-hx + arm_w, -hy + back_t, seat - cushion], [hx - arm_w, hy, seat], SOFT)
    return a


def chair(rng: np.random.Generator) -> Assembly:
    """Chair: seat on four legs and a back rest (at -y)."""
    a = Assembly("chair")
    width, depth, seat = rng.uniform(0.4, 0.5), rng.uniform(0.4, 0.5), rng.uniform(0.43, 0.48)
    t, hx, hy = rng.uniform(0.03, 0.05), width / 2, depth / 2
    _slab_on_legs(a, "seat", hx, hy, seat, t, rng.uniform(0.025, 0.04), 0.0, rng)
    a.box("back", [-hx, -hy, seat], [hx, -hy + rng.uniform(0.02, 0.04), seat + rng.uniform(0.35, 0.5)])
    return a


def storage_box(rng: np.random.Generator, small: bool = False) -> Assembly:
    """A single box: a crate on the floor, or (``small``) a carton on a table or shelf."""
    a = Assembly("box")
    if small:
        size = [rng.uniform(0.08, 0.35), rng.uniform(0.08, 0.3), rng.uniform(0.04, 0.3)]
    else:
        size = [rng.uniform(0.25, 0.6), rng.uniform(0.25, 0.5), rng.uniform(0.2, 0.55)]
    a.box("box", [-size[0] / 2, -size[1] / 2, 0.0], [size[0] / 2, size[1] / 2, size[2]])
    a.surface(size[2], [-size[0] / 2, -size[1] / 2], [size[0] / 2, size[1] / 2], margin=0.0)
    return a


def wall_cupboard(rng: np.random.Generator) -> Assembly:
    """Wall-mounted cupboard (its back at -y against the wall), bottom 1.4-1.7 m above the floor."""
    a = Assembly("wall_cupboard")
    width, depth, height, bottom = (
        rng.uniform(0.5, 1.2),
        rng.uniform(0.3, 0.38),
        rng.uniform(0.5, 0.8),
        rng.uniform(1.4, 1.7),
    )
    a.box("body", [-width / 2, -depth / 2, bottom], [width / 2, depth / 2, bottom + height])
    return a


def books(rng: np.random.Generator) -> Assembly:
    """A few books standing side by side, or a flat stack."""
    a = Assembly("book")
    depth, n = rng.uniform(0.15, 0.24), int(rng.integers(1, 5))
    if rng.random() < 0.5:
        x = 0.0
        for _ in range(n):
            t, h = rng.uniform(0.015, 0.05), rng.uniform(0.18, 0.3)
            a.box("book", [x, -depth / 2, 0.0], [x + t, depth / 2, h])
            x += t
        for p in a.parts:  # centre the row on the origin
            p.lo[0] -= x / 2
            p.hi[0] -= x / 2
    else:
        z = 0.0
        for _ in range(n):
            w, t = rng.uniform(0.13, 0.2), rng.uniform(0.015, 0.05)
            a.box("book", [-w / 2, -depth / 2, z], [w / 2, depth / 2, z + t])
            z += t
    return a


def monitor(rng: np.random.Generator) -> Assembly:
    """Flat screen on a stand: base plate, neck and panel."""
    a = Assembly("monitor")
    w, h, lift = rng.uniform(0.45, 0.65), rng.uniform(0.28, 0.4), rng.uniform(0.06, 0.12)
    a.box("base", [-0.11, -0.09, 0.0], [0.11, 0.09, 0.015], METAL)
    a.box("neck", [-0.025, -0.05, 0.015], [0.025, -0.02, lift + 0.02], METAL)
    a.box("screen", [-w / 2, -0.02, lift], [w / 2, 0.01, lift + h], ACCENT)
    return a


#: Floor furniture: generator, relative frequency, probability of standing against a wall.
FLOOR_FURNITURE: dict[str, tuple[Callable[[np.random.Generator], Assembly], float, float]] = {
    "table": (table, 1.0, 0.15),
    "desk": (desk, 0.7, 0.85),
    "bed": (bed, 0.5, 0.95),
    "cabinet": (cabinet, 1.2, 0.85),
    "shelf": (shelf, 0.9, 0.95),
    "sofa": (sofa, 0.6, 0.7),
    "chair": (chair, 1.0, 0.1),
    "box": (storage_box, 0.6, 0.3),
}

#: Small box objects placed on support surfaces: generator and relative frequency.
SMALL_OBJECTS: dict[str, tuple[Callable[[np.random.Generator], Assembly], float]] = {
    "box": (lambda rng: storage_box(rng, small=True), 1.0),
    "book": (books, 1.0),
    "monitor": (monitor, 0.3),
}

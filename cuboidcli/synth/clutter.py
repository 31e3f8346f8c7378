"""Non-box clutter (so that not everything is a cuboid): cylinders, spheres, cones and irregular low-poly
blobs, built in the object frame (origin on the supporting surface, z up), sizes in metres."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, field
from functools import partial

import numpy as np

from cuboidcli.synth.furniture import ACCENT, MAIN, METAL, SOFT
from cuboidcli.synth.mesh import blob_mesh, frustum_mesh, sphere_mesh

LEAF, SKIN = "leaf", "skin"


@dataclass
class MeshAssembly:
    """A clutter object: pieces (vertices (V, 3), faces (F, 3), role) in the object frame."""

    category: str
    pieces: list[tuple[np.ndarray, np.ndarray, str]] = field(default_factory=list)

    def add(self, mesh: tuple[np.ndarray, np.ndarray], role: str, offset=(0.0, 0.0, 0.0)) -> None:
        v, f = mesh
        self.pieces.append((v + np.asarray(offset, float), f, role))

    def bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """Corners (3,), (3,) of the axis-aligned box around every vertex."""
        allv = np.concatenate([v for v, _, _ in self.pieces])
        return allv.min(0), allv.max(0)


def waste_bin(rng: np.random.Generator) -> MeshAssembly:
    a = MeshAssembly("bin")
    r = rng.uniform(0.11, 0.18)
    a.add(frustum_mesh(r, r * rng.uniform(1.0, 1.2), rng.uniform(0.3, 0.5), segments=14), MAIN)
    return a


def floor_lamp(rng: np.random.Generator) -> MeshAssembly:
    a = MeshAssembly("lamp")
    pole = rng.uniform(1.3, 1.6)
    a.add(frustum_mesh(rng.uniform(0.12, 0.16), 0.1, 0.03), METAL)
    a.add(frustum_mesh(0.012, 0.012, pole, segments=8), METAL, (0.0, 0.0, 0.03))
    rb = rng.uniform(0.18, 0.25)
    a.add(frustum_mesh(rb, rb * rng.uniform(0.5, 0.7), rng.uniform(0.2, 0.3)), SOFT, (0.0, 0.0, pole - 0.1))
    return a


def table_lamp(rng: np.random.Generator) -> MeshAssembly:
    a = MeshAssembly("lamp")
    stem = rng.uniform(0.15, 0.3)
    a.add(frustum_mesh(0.07, 0.05, 0.02), METAL)
    a.add(frustum_mesh(0.01, 0.01, stem, segments=8), METAL, (0.0, 0.0, 0.02))
    rb = rng.uniform(0.1, 0.15)
    a.add(frustum_mesh(rb, rb * 0.6, rng.uniform(0.12, 0.18)), SOFT, (0.0, 0.0, stem - 0.02))
    return a


def pipe(rng: np.random.Generator, height: float) -> MeshAssembly:
    """A vertical pipe from floor to ceiling (``height`` metres); the frame origin is on its axis."""
    a = MeshAssembly("pipe")
    r = rng.uniform(0.03, 0.08)
    a.add(frustum_mesh(r, r, height, segments=12), METAL)
    return a


def ball(rng: np.random.Generator, radius=(0.1, 0.3), lat: int = 8, lon: int = 14) -> MeshAssembly:
    """A ball lying on the surface: radius drawn from the range ``radius``, ``lat`` x ``lon`` segments."""
    a = MeshAssembly("ball")
    r = rng.uniform(*radius)
    a.add(sphere_mesh(r, lat=lat, lon=lon), MAIN, (0.0, 0.0, r))
    return a


def cone(rng: np.random.Generator, radius=(0.1, 0.25), height=(0.3, 0.7), segments: int = 16) -> MeshAssembly:
    """A cone standing on its base: base radius and height drawn from the ranges ``radius`` and ``height``."""
    a = MeshAssembly("cone")
    a.add(frustum_mesh(rng.uniform(*radius), 0.0, rng.uniform(*height), segments=segments), MAIN)
    return a


def plant(rng: np.random.Generator) -> MeshAssembly:
    a = MeshAssembly("plant")
    rb, h = rng.uniform(0.1, 0.15), rng.uniform(0.2, 0.35)
    a.add(frustum_mesh(rb, rb * rng.uniform(1.2, 1.4), h, segments=12), ACCENT)
    radii = [rng.uniform(0.2, 0.4), rng.uniform(0.2, 0.4), rng.uniform(0.3, 0.6)]
    v, f = blob_mesh(radii, rng, roughness=0.3)
    # The foliage sits 0.8 r_z above the pot's rim, but a rough blob's bumps reach up to 1.3 r_z below its
    # centre: lift those few that would reach through the floor to stand on it.
    a.add((v, f), LEAF, (0.0, 0.0, max(h + 0.8 * radii[2], -float(v[:, 2].min()))))
    return a


def bag(rng: np.random.Generator) -> MeshAssembly:
    a = MeshAssembly("bag")
    radii = [rng.uniform(0.15, 0.25), rng.uniform(0.1, 0.15), rng.uniform(0.15, 0.25)]
    v, f = blob_mesh(radii, rng, roughness=0.15)
    a.add((v, f), SOFT, (0.0, 0.0, -v[:, 2].min()))
    return a


def person(rng: np.random.Generator) -> MeshAssembly:
    """A people-sized blob: body and head, 1.5-1.85 m tall."""
    a = MeshAssembly("person")
    height, head = rng.uniform(1.5, 1.85), rng.uniform(0.1, 0.12)
    body_h = (height - 2 * head) / 2
    v, f = blob_mesh([rng.uniform(0.18, 0.25), rng.uniform(0.12, 0.17), body_h], rng, roughness=0.08)
    a.add((v, f), SOFT, (0.0, 0.0, -v[:, 2].min()))
    a.add(blob_mesh([head, head, head * 1.15], rng, roughness=0.05), SKIN, (0.0, 0.0, height - head))
    return a


def vase(rng: np.random.Generator) -> MeshAssembly:
    a = MeshAssembly("vase")
    r = rng.uniform(0.035, 0.08)
    a.add(frustum_mesh(r, r * rng.uniform(0.6, 1.3), rng.uniform(0.08, 0.3), segments=12), MAIN)
    return a


#: Clutter standing on the floor: generator and relative frequency (pipes are placed separately).
FLOOR_CLUTTER: dict[str, tuple[Callable[[np.random.Generator], MeshAssembly], float]] = {
    "bin": (waste_bin, 1.0),
    "lamp": (floor_lamp, 0.7),
    "ball": (ball, 0.6),
    "cone": (cone, 0.4),
    "plant": (plant, 1.0),
    "bag": (bag, 0.7),
    "person": (person, 0.5),
}

#: Clutter standing on tables and shelves.
SMALL_CLUTTER: dict[str, tuple[Callable[[np.random.Generator], MeshAssembly], float]] = {
    "vase": (vase, 1.0),
    "lamp": (table_lamp, 0.5),
    "ball": (partial(ball, radius=(0.04, 0.1), lat=7, lon=12), 0.4),
    "cone": (partial(cone, radius=(0.04, 0.08), height=(0.1, 0.25), segments=12), 0.3),
}

"""Triangle meshes of the primitives (box, frustum/cylinder/cone, sphere, low-poly blob) and the
scene's triangle soup with per-face attributes, ready for the ray caster.

Local meshes are built around the origin (frustums stand on z = 0 and rise along +z); callers place them
with a rotation and an offset. Faces are wound counter-clockwise seen from outside.
"""

from __future__ import annotations

from dataclasses import dataclass
from itertools import product

import numpy as np

from cuboidcli.synth.world import World

_BOX_SIGNS = np.array(list(product((-1.0, 1.0), repeat=3)))  # corner k of Cuboid.corners()


def _orient_outward(vertices: np.ndarray, faces: np.ndarray, center: np.ndarray) -> np.ndarray:
    """Flip faces whose normal points towards ``center`` (valid for convex and star-shaped meshes)."""
    a, b, c = (vertices[faces[:, k]] for k in range(3))
    normal = np.cross(b - a, c - a)
    inward = np.einsum("fk,fk->f", normal, (a + b + c) / 3.0 - center) < 0
    faces = faces.copy()
    faces[inward] = faces[inward][:, ::-1]
    return faces


def _unit_box_faces() -> np.ndarray:
    """The 12 outward-wound triangles over the 8 corners of :data:`_BOX_SIGNS`: (12, 3)."""
    faces = []
    for axis in range(3):
        b, c = (axis + 1) % 3, (axis + 2) % 3
        for sign in (-1.0, 1.0):
            # the side's four corners in cyclic order over the two tangential axes
            loop = []
            for sb, sc in ((-1, -1), (1, -1), (1, 1), (-1, 1)):
                s = np.zeros(3)
                s[axis], s[b], s[c] = sign, sb, sc
                loop.append(int(np.flatnonzero((_BOX_SIGNS == s).all(1))[0]))
            faces += [(loop[0], loop[1], loop[2]), (loop[0], loop[2], loop[3])]
    return _orient_outward(_BOX_SIGNS, np.array(faces, dtype=np.int64), np.zeros(3))


def box_mesh(center, half_size, rotation) -> tuple[np.ndarray, np.ndarray]:
    """Box with centre (3,), half-sizes (3,), rotation (3, 3): vertices (8, 3), faces (12, 3).

    A rotation and positive scaling keep the unit box's outward winding, so the faces are shared.
    """
    local = _BOX_SIGNS * np.asarray(half_size, float)
    vertices = local @ np.asarray(rotation, float).T + np.asarray(center, float)
    return vertices, _BOX_FACES.copy()


_BOX_FACES = _unit_box_faces()


def frustum_mesh(
    r_bottom: float, r_top: float, height: float, segments: int = 16, phase: float = 0.0
) -> tuple[np.ndarray, np.ndarray]:
    """Truncated cone on z = 0 rising to z = height (a cylinder if the radii agree, a cone if r_top = 0).

    Returns vertices (2 * segments + 2, 3) and faces; closed by caps.
    """
    ang = phase + 2.0 * np.pi * np.arange(segments) / segments
    ring = np.stack([np.cos(ang), np.sin(ang), np.zeros(segments)], -1)
    bottom = ring * [r_bottom, r_bottom, 0.0]
    top = ring * [r_top, r_top, 0.0] + [0.0, 0.0, height]
    vertices = np.concatenate([bottom, top, [[0.0, 0.0, 0.0], [0.0, 0.0, height]]])
    i = np.arange(segments)
    j = (i + 1) % segments
    cb, ct = 2 * segments, 2 * segments + 1
    faces = [
        np.stack([i, j, segments + j], -1),
        np.stack([i, segments + j, segments + i], -1),
        np.stack([np.full(segments, cb), j, i], -1),
    ]
    if r_top > 0:
        faces.append(np.stack([np.full(segments, ct), segments + i, segments + j], -1))
    faces = np.concatenate(faces).astype(np.int64)
    return vertices, _orient_outward(vertices, faces, np.array([0.0, 0.0, height / 2.0]))


def sphere_mesh(radius: float, lat: int = 8, lon: int = 14) -> tuple[np.ndarray, np.ndarray]:
    """Low-poly UV sphere centred on the origin: vertices ((lat - 1) * lon + 2, 3) and faces."""
    theta = np.pi * np.arange(1, lat) / lat
    phi = 2.0 * np.pi * np.arange(lon) / lon
    t, p = np.meshgrid(theta, phi, indexing="ij")
    ring = np.stack([np.sin(t) * np.cos(p), np.sin(t) * np.sin(p), np.cos(t)], -1).reshape(-1, 3)
    vertices = np.concatenate([[[0.0, 0.0, 1.0]], ring, [[0.0, 0.0, -1.0]]]) * radius
    faces = []
    south = len(vertices) - 1
    for k in range(lon):
        k2 = (k + 1) % lon
        faces.append((0, 1 + k, 1 + k2))
        last = 1 + (lat - 2) * lon
        faces.append((south, last + k2, last + k))
        for r in range(lat - 2):
            a, b = 1 + r * lon + k, 1 + r * lon + k2
            faces += [(a, a + lon, b + lon), (a, b + lon, b)]
    faces = np.array(faces, dtype=np.int64)
    return vertices, _orient_outward(vertices, faces, np.zeros(3))


def blob_mesh(radii, rng: np.random.Generator, roughness: float = 0.25) -> tuple[np.ndarray, np.ndarray]:
    """Irregular low-poly blob (plant foliage, bag, person): an ellipsoid with radii (3,) whose surface
    is pushed in and out by a few random low-frequency waves of relative amplitude ``roughness``."""
    vertices, faces = sphere_mesh(1.0, lat=7, lon=11)
    dirs = rng.normal(size=(4, 3))
    freq = rng.uniform(1.5, 3.5, 4)
    phase = rng.uniform(0.0, 2.0 * np.pi, 4)
    bump = np.sin(vertices @ (dirs * freq[:, None]).T + phase).mean(1)
    vertices = vertices * (1.0 + roughness * bump)[:, None] * np.asarray(radii, float)
    return vertices, _orient_outward(vertices, faces, np.zeros(3))


@dataclass
class Soup:
    """All triangles of a world with per-face attributes (F = number of faces).

    ``vertices`` (V, 3) float64 world metres; ``faces`` (F, 3) int64; ``object_id`` (F,) instance id;
    ``part`` (F,) index into ``World.parts`` or -1 for clutter; ``material`` (F,) index into
    ``World.materials``; ``frame`` (F,) index into ``frame_rotation`` (T, 3, 3) / ``frame_origin`` (T, 3),
    the texture frames (a box's own frame, a mesh's object frame); ``frame_half`` (T, 3) is a box's
    half-sizes (zeros for meshes), so that wood grain can follow a board's long side.
    """

    vertices: np.ndarray
    faces: np.ndarray
    object_id: np.ndarray
    part: np.ndarray
    material: np.ndarray
    frame: np.ndarray
    frame_rotation: np.ndarray
    frame_origin: np.ndarray
    frame_half: np.ndarray


def build_soup(world: World) -> Soup:
    """Triangulate every box part and mesh of ``world`` into one :class:`Soup`."""
    verts, faces, oid, part, mat, frame, rots, origins, halves = [], [], [], [], [], [], [], [], []
    offset = 0

    def add(v, f, object_id, part_index, material, rotation, origin, half):
        nonlocal offset
        verts.append(v)
        faces.append(f + offset)
        offset += len(v)
        n = len(f)
        oid.append(np.full(n, object_id))
        part.append(np.full(n, part_index))
        mat.append(np.full(n, material))
        frame.append(np.full(n, len(rots)))
        rots.append(rotation)
        origins.append(origin)
        halves.append(half)

    for k, p in enumerate(world.parts):
        v, f = box_mesh(p.center, p.half_size, p.rotation)
        add(v, f, p.object_id, k, p.material, p.rotation, p.center, p.half_size)
    for m in world.meshes:
        add(m.vertices, m.faces, m.object_id, -1, m.material, m.frame[0], m.frame[1], np.zeros(3))
    cat = np.concatenate
    return Soup(
        cat(verts),
        cat(faces).astype(np.int64),
        cat(oid).astype(np.int32),
        cat(part).astype(np.int32),
        cat(mat).astype(np.int32),
        cat(frame).astype(np.int32),
        np.stack(rots),
        np.stack(origins),
        np.stack(halves),
    )

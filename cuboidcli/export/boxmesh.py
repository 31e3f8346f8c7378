"""Box topology shared by every exporter: corner order, the 12 edges and the 6 outward-facing quads.

Corner ``k`` of a cuboid has local signs ``CORNER_SIGNS[k]`` (the order of :meth:`Cuboid.corners`,
``itertools.product((-1, 1), repeat=3)``), so corner ``k`` sits at
``rotation @ (signs * half_size) + center``.
"""

from __future__ import annotations

from itertools import product

import numpy as np

#: (8, 3) local signs of the corners, in the order of :meth:`cuboidcli.cuboid.Cuboid.corners`.
CORNER_SIGNS: np.ndarray = np.array(list(product((-1.0, 1.0), repeat=3)))


def _corner_index(signs: tuple[float, float, float]) -> int:
    """Index into CORNER_SIGNS of the corner with local signs (sx, sy, sz)."""
    return int(sum((s > 0) << (2 - axis) for axis, s in enumerate(signs)))


def _edges() -> np.ndarray:
    """(12, 2) corner pairs that differ in exactly one sign."""
    pairs = [
        (i, j)
        for i in range(8)
        for j in range(i + 1, 8)
        if int(np.sum(CORNER_SIGNS[i] != CORNER_SIGNS[j])) == 1
    ]
    return np.array(pairs, dtype=np.int64)


def _quads() -> tuple[np.ndarray, np.ndarray]:
    """(6, 4) corner indices per side, counter-clockwise seen from outside, and (6, 3) outward normals.

    Side order: -x, +x, -y, +y, -z, +z. For axis i with the cyclic partners j, k we have e_j x e_k = e_i,
    so walking (-,-), (+,-), (+,+), (-,+) in the (j, k) plane is counter-clockwise around +e_i; the -e_i
    side walks the same loop backwards.
    """
    quads, normals = [], []
    for axis in range(3):
        j, k = (axis + 1) % 3, (axis + 2) % 3
        for side in (-1.0, 1.0):
            loop = []
            for sj, sk in ((-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)):
                signs = [0.0, 0.0, 0.0]
                signs[axis], signs[j], signs[k] = side, sj, sk
                loop.append(_corner_index(tuple(signs)))
            quads.append(loop if side > 0 else loop[::-1])
            n = np.zeros(3)
            n[axis] = side
            normals.append(n)
    return np.array(quads, dtype=np.int64), np.array(normals)


#: (12, 2) corner indices of the box edges.
BOX_EDGES: np.ndarray = _edges()
#: (6, 4) corner indices of the sides (counter-clockwise from outside) and (6, 3) their local outward normals.
BOX_QUADS, SIDE_NORMALS = _quads()
#: (12, 3) triangles over the 8 corners, wound counter-clockwise seen from outside.
BOX_TRIANGLES: np.ndarray = np.concatenate([BOX_QUADS[:, [0, 1, 2]], BOX_QUADS[:, [0, 2, 3]]], axis=0)


def local_corners(half_size: np.ndarray) -> np.ndarray:
    """(8, 3) corners of the box with half-sizes ``half_size`` (3,) m, in its own frame."""
    return CORNER_SIGNS * np.asarray(half_size, dtype=np.float64).reshape(1, 3)


def flat_box(half_size: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """A flat-shaded box in its own frame: vertices (24, 3) m, triangles (12, 3), vertex normals (24, 3).

    Each side gets its own four vertices so that renderers do not smooth the normals across the edges.
    Vertex ``4 * s + q`` is corner ``BOX_QUADS[s, q]``.
    """
    corners = local_corners(half_size)
    vertices = corners[BOX_QUADS.reshape(-1)]
    normals = np.repeat(SIDE_NORMALS, 4, axis=0)
    base = 4 * np.arange(6)[:, None]
    faces = np.concatenate([base + np.array([0, 1, 2]), base + np.array([0, 2, 3])], axis=0)
    return vertices, faces.astype(np.int64), normals

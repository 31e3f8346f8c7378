"""PLY export for MeshLab and CloudCompare: the input point cloud coloured by cuboid, and the cuboid meshes.

Both files stay in the OpenCV camera frame (x right, y down, z forward, metres), the frame of the result
JSON, so they overlay each other and the JSON's numbers directly; a ``comment frame`` header line says so.
Binary little-endian PLY: float32 coordinates, uchar colours.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid, palette_color
from cuboidcli.export.boxmesh import flat_box
from cuboidcli.io.atomic import atomic_write

#: Colour (RGB) of points that are no cuboid's inlier (label -1).
UNASSIGNED_RGB: tuple[int, int, int] = (128, 128, 128)
#: Colour (RGB) of points hidden behind a cuboid side, i.e. the cuboid sits in front of them (label -2).
OCCLUDED_RGB: tuple[int, int, int] = (0, 0, 0)
_FRAME_COMMENT = "comment frame opencv camera (x right, y down, z forward), metres"


def label_colors(labels: np.ndarray) -> np.ndarray:
    """Per-point colours (N, 3) uint8 for labels (N,): k >= 0 cuboid k's palette colour, -1 grey, -2 black."""
    labels = np.asarray(labels, dtype=np.int64).reshape(-1)
    if labels.size and labels.min() < -2:
        raise ValueError(f"point labels must be >= -2, got {int(labels.min())}")
    n_cuboids = max(int(labels.max()) + 1, 0) if labels.size else 0
    table = np.array(
        [OCCLUDED_RGB, UNASSIGNED_RGB, *(palette_color(k) for k in range(n_cuboids))], dtype=np.uint8
    )
    return table[labels + 2]


def depth_points(depth_m: np.ndarray, camera: Camera, step: int = 1) -> tuple[np.ndarray, np.ndarray]:
    """Valid back-projected points (N, 3) m of a depth map (H, W) m and their flat pixel indices (N,).

    ``step`` keeps every step-th pixel in both directions; the indices address the full (H, W) image.
    """
    pts = camera.backproject(depth_m, step)
    ok = valid_depth(depth_m[::step, ::step])
    rows, cols = np.nonzero(ok)
    return pts[rows, cols], (rows * step) * camera.width + cols * step


def assign_labels(points: np.ndarray, cuboids: list[Cuboid], settings: dict | None = None) -> np.ndarray:
    """Label (N,) int32 per point (N, 3) m: cuboid index, -1 none, -2 occluded by a cuboid.

    Uses the fitting's inlier threshold tau, beta, tau_c and occlusion-awareness from ``settings`` (the
    result's resolved FitConfig) when present, so that the colours match what the fit counted as inliers.
    """
    from cuboidcli.fitting.assign import assign_points
    from cuboidcli.fitting.scoring import ScoreParams

    if len(cuboids) == 0 or len(points) == 0:
        return np.full(len(points), -1, dtype=np.int32)
    sp = ScoreParams.of(settings or {})
    return np.asarray(assign_points(np.asarray(points, dtype=np.float64), cuboids, sp), dtype=np.int32)


#: The vertex element's properties, in the order of :func:`_vertex_records`' fields.
_VERTEX_PROPS = [
    "property float x",
    "property float y",
    "property float z",
    "property uchar red",
    "property uchar green",
    "property uchar blue",
]


def _vertex_records(points: np.ndarray, colors: np.ndarray) -> np.ndarray:
    """Binary vertex records (N,) for points (N, 3) m and colours (N, 3) uint8: float32 xyz, uchar RGB."""
    rec = np.empty(
        len(points),
        dtype=[("x", "<f4"), ("y", "<f4"), ("z", "<f4"), ("red", "u1"), ("green", "u1"), ("blue", "u1")],
    )
    rec["x"], rec["y"], rec["z"] = points[:, 0], points[:, 1], points[:, 2]
    rec["red"], rec["green"], rec["blue"] = colors[:, 0], colors[:, 1], colors[:, 2]
    return rec


def _header(comments: list[str], elements: list[tuple[str, int, list[str]]]) -> bytes:
    lines = ["ply", "format binary_little_endian 1.0", *comments]
    for name, count, props in elements:
        lines.append(f"element {name} {count}")
        lines.extend(props)
    lines.append("end_header")
    return ("\n".join(lines) + "\n").encode("ascii")


def write_point_ply(path: str | os.PathLike, points: np.ndarray, colors: np.ndarray) -> Path:
    """Write points (N, 3) m with colours (N, 3) uint8 RGB as a binary PLY, atomically. Returns ``path``."""
    points = np.asarray(points, dtype=np.float64).reshape(-1, 3)
    colors = np.asarray(colors, dtype=np.uint8).reshape(-1, 3)
    if len(points) != len(colors):
        raise ValueError(f"{len(points)} points but {len(colors)} colours")
    head = _header([_FRAME_COMMENT], [("vertex", len(points), _VERTEX_PROPS)])
    return atomic_write(path, lambda p: p.write_bytes(head + _vertex_records(points, colors).tobytes()))


def cuboid_mesh_arrays(cuboids: list[Cuboid]) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Flat-shaded meshes of all cuboids in camera coordinates.

    Returns vertices (24 M, 3) m, triangles (12 M, 3) and vertex colours (24 M, 3) uint8 (palette order).
    """
    verts, faces, cols = [], [], []
    for k, cub in enumerate(cuboids):
        v, f, _ = flat_box(cub.half_size)
        verts.append(v @ cub.rotation.T + cub.center)
        faces.append(f + 24 * k)
        cols.append(np.tile(np.array(palette_color(k), dtype=np.uint8), (24, 1)))
    if not cuboids:
        return np.zeros((0, 3)), np.zeros((0, 3), dtype=np.int64), np.zeros((0, 3), dtype=np.uint8)
    return np.concatenate(verts), np.concatenate(faces), np.concatenate(cols)


def write_cuboid_ply(path: str | os.PathLike, cuboids: list[Cuboid]) -> Path:
    """Write the cuboids as one triangle mesh (24 vertices, 12 triangles each) with vertex colours."""
    verts, faces, cols = cuboid_mesh_arrays(cuboids)
    vrec = _vertex_records(verts, cols)
    frec = np.empty(len(faces), dtype=[("n", "u1"), ("idx", "<i4", (3,))])
    frec["n"] = 3
    frec["idx"] = faces
    head = _header(
        [_FRAME_COMMENT, f"comment {len(cuboids)} cuboids, 24 vertices and 12 faces each, in palette order"],
        [
            ("vertex", len(verts), _VERTEX_PROPS),
            ("face", len(faces), ["property list uchar int vertex_indices"]),
        ],
    )
    return atomic_write(path, lambda p: p.write_bytes(head + vrec.tobytes() + frec.tobytes()))

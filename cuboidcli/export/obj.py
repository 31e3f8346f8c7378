"""Wavefront OBJ export: one object ``cuboid_00``, ``cuboid_01``, ... per cuboid, colours in a .mtl beside it.

OBJ files are conventionally +Y up (Blender's importer assumes it), so vertices are written in the glTF
frame ``diag(1, -1, -1) *`` OpenCV camera frame, metres, and line up with the GLB export.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from cuboidcli.cuboid import Cuboid, palette_color
from cuboidcli.export.boxmesh import BOX_QUADS, SIDE_NORMALS
from cuboidcli.export.glb import gltf_points, node_name
from cuboidcli.io.atomic import atomic_write_text


def obj_text(cuboids: list[Cuboid], mtl_name: str) -> str:
    """OBJ source: 8 vertices, 6 normals and 6 quads per cuboid, in the glTF frame."""
    lines = [
        "# cuboids: one object per cuboid; frame x right, y up, z backward (glTF), metres",
        f"mtllib {mtl_name}",
    ]
    for k, cub in enumerate(cuboids):
        corners = gltf_points(cub.corners())
        # A proper rotation (F R) maps local normals; the frame flip F keeps winding because F is a rotation.
        normals = gltf_points(SIDE_NORMALS @ cub.rotation.T)
        lines += [f"o {node_name(cuboids, k)}", f"usemtl {node_name(cuboids, k)}"]
        lines += [f"v {x:.6f} {y:.6f} {z:.6f}" for x, y, z in corners]
        lines += [f"vn {x:.6f} {y:.6f} {z:.6f}" for x, y, z in normals]
        v0, n0 = 8 * k + 1, 6 * k + 1
        for s, quad in enumerate(BOX_QUADS):
            lines.append("f " + " ".join(f"{v0 + int(q)}//{n0 + s}" for q in quad))
    return "\n".join(lines) + "\n"


def mtl_text(cuboids: list[Cuboid]) -> str:
    """Material library with one diffuse colour per cuboid (palette order), named like the cuboids."""
    lines = ["# cuboids materials, palette order"]
    for k in range(len(cuboids)):
        r, g, b = (np.array(palette_color(k)) / 255.0).tolist()
        lines += [
            f"newmtl {node_name(cuboids, k)}",
            f"Kd {r:.4f} {g:.4f} {b:.4f}",
            "Ka 0 0 0",
            "Ks 0 0 0",
            "d 1",
            "illum 1",
            "",
        ]
    return "\n".join(lines)


def write_obj(path: str | os.PathLike, cuboids: list[Cuboid]) -> tuple[Path, Path]:
    """Write ``path`` (.obj) and its material library beside it (same name, .mtl), atomically each."""
    path = Path(path)
    mtl = path.with_name(path.stem + ".mtl")
    atomic_write_text(mtl, mtl_text(cuboids))
    atomic_write_text(path, obj_text(cuboids, mtl.name))
    return path, mtl

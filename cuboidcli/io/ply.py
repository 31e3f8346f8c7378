"""The vertices of a binary PLY point cloud read with numpy alone.

Most scans are stored as binary PLY files whose only element is the vertex: coordinates, perhaps colours
and normals (ScanNet's, Open3D's and most scanners' exports). Those are one fixed-size record per point,
read here in one ``numpy.fromfile`` call, which spares a room the 0.4-0.5 s of importing Open3D. Anything
else (ASCII, list properties among the vertex's, an element stored before the vertices) is left to the
general reader: :func:`read_ply_vertices` returns None for it.
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

_TYPES = {
    "char": "i1", "int8": "i1", "uchar": "u1", "uint8": "u1",
    "short": "i2", "int16": "i2", "ushort": "u2", "uint16": "u2",
    "int": "i4", "int32": "i4", "uint": "u4", "uint32": "u4",
    "float": "f4", "float32": "f4", "double": "f8", "float64": "f8",
}  # fmt: skip
_ORDER = {"binary_little_endian": "<", "binary_big_endian": ">"}
#: Longest header read (bytes): headers are a few hundred bytes; comments may add some.
_HEADER_LIMIT = 1 << 16


def _layout(path: Path) -> tuple[np.dtype, int, int] | None:
    """(record dtype, vertex count, byte offset of the first record) of a binary PLY whose first element
    is the vertex with scalar properties only, else None."""
    with open(path, "rb") as f:
        head = f.read(_HEADER_LIMIT)
    end = head.find(b"end_header")
    if not head.startswith(b"ply") or end < 0:
        return None
    newline = head.find(b"\n", end)
    if newline < 0:
        return None
    order, count, fields, element = None, None, [], None
    for raw in head[:end].split(b"\n")[1:]:
        parts = raw.decode("latin-1").split()
        if not parts or parts[0] in ("comment", "obj_info"):
            continue
        if parts[0] == "format" and len(parts) >= 2:
            order = _ORDER.get(parts[1])
        elif parts[0] == "element" and len(parts) == 3:
            if element is not None:  # a second element: fine only after the vertices
                if element == "vertex":
                    break
                return None
            element = parts[1]
            if element != "vertex" or not parts[2].isdigit():
                return None
            count = int(parts[2])
        elif parts[0] == "property" and element == "vertex":
            if len(parts) != 3 or parts[1] not in _TYPES:
                return None  # a list property or an unknown type
            fields.append((parts[2], (order or "<") + _TYPES[parts[1]]))
    names = [name for name, _ in fields]
    if order is None or count is None or len(set(names)) != len(names):
        return None
    return np.dtype(fields), count, newline + 1


def read_ply_vertices(path: Path) -> tuple[np.ndarray, np.ndarray | None, np.ndarray | None] | None:
    """(points (N, 3) float64, colours (N, 3) as stored or None, normals (N, 3) float64 or None) of a
    binary vertex-only PLY point cloud; None where the file has another layout.

    Raises ValueError when its vertices lack x, y or z, or the file holds fewer bytes than its header
    declares (truncated)."""
    layout = _layout(path)
    if layout is None:
        return None
    dtype, count, offset = layout
    names = dtype.names or ()
    if not {"x", "y", "z"} <= set(names):
        missing = ", ".join(k for k in "xyz" if k not in names)
        raise ValueError(f"its vertices have no {missing} (properties: {', '.join(names) or 'none'})")
    available = (path.stat().st_size - offset) // dtype.itemsize if dtype.itemsize else 0
    if available < count:
        raise ValueError(f"the file is truncated ({count} points declared, {available} stored)")
    rec = np.fromfile(path, dtype=dtype, count=count, offset=offset)
    points = np.stack([rec[k].astype(np.float64) for k in ("x", "y", "z")], axis=1)
    colors = None
    for keys in (("red", "green", "blue"), ("diffuse_red", "diffuse_green", "diffuse_blue")):
        if set(keys) <= set(names):
            colors = np.stack([rec[k] for k in keys], axis=1)
            break
    normals = None
    if {"nx", "ny", "nz"} <= set(names):
        normals = np.stack([rec[k].astype(np.float64) for k in ("nx", "ny", "nz")], axis=1)
    return points, colors, normals

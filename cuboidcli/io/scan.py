"""Reading a whole scene given as a point cloud or a mesh into one :class:`PointCloud`.

Files: ``.ply`` (points, or a mesh when it has faces), ``.pcd`` (Open3D), ``.obj`` / ``.glb`` / ``.gltf``
(trimesh; a scene's meshes are joined with their node transforms), ``.npy`` (an (N, 3) or (N, 6) array:
xyz, or xyz + rgb in 0-255 or 0-1) and ``.npz`` (``points`` or ``xyz``, optional ``colors`` or ``rgb``,
optional ``normals``). Meshes are sampled uniformly by area. The coordinates are the file's, as stored:
the room loader (:mod:`cuboidcli.load.units`) scales them by the unit they are in and checks that they can
be a room. Every problem raises :class:`InputError` with a one-line message.
"""

from __future__ import annotations

import os
import zipfile
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cuboidcli.io.depth import InputError, _one_line
from cuboidcli.io.ply import read_ply_vertices

SCAN_SUFFIXES = (".ply", ".pcd", ".obj", ".glb", ".gltf", ".npy", ".npz")
#: Metres per coordinate unit a file may be stored in (``--unit``); the room loader scales by it
#: (:mod:`cuboidcli.load.units`), the settings' checks name the choices.
UNITS = {"m": 1.0, "cm": 0.01, "mm": 0.001}
MESH_SUFFIXES = (".obj", ".glb", ".gltf")
#: Fewest points a room can be fitted from (and so the fewest a mesh is sampled to).
MIN_POINTS = 100
#: Grey for parts of a mesh without colour when other parts have one.
_GREY = 128


@dataclass
class PointCloud:
    """A scene as points in the input's own world frame.

    ``points`` (N, 3) float64: a file's coordinates as stored when :func:`read_scan` returns them, metres
    once loaded as a room; ``colors`` (N, 3) uint8 or None; ``normals`` (N, 3) float64 unit vectors or None;
    ``viewpoints`` (N, 3) float64 metres: the centre of a camera that observed each point
    (fused sequences), else None; ``frames`` (N,) int32 index into ``frame_names`` of that observation's
    frame, else None. ``meta`` is JSON-able provenance, ``warnings`` one line each.
    """

    points: np.ndarray
    colors: np.ndarray | None = None
    normals: np.ndarray | None = None
    viewpoints: np.ndarray | None = None
    frames: np.ndarray | None = None
    frame_names: list[str] = field(default_factory=list)
    meta: dict = field(default_factory=dict)
    warnings: list[str] = field(default_factory=list)

    def __len__(self) -> int:
        return int(self.points.shape[0])


def is_scan_file(path: str | os.PathLike) -> bool:
    """Whether ``path`` has a point-cloud or mesh suffix (case-insensitive); the file need not exist."""
    return Path(path).suffix.lower() in SCAN_SUFFIXES


def _colors_u8(colors: np.ndarray, what: str) -> np.ndarray:
    """(N, 3) colours in 0-255, or 0-1 (floats with a maximum <= 1), as uint8."""
    colors = np.asarray(colors)
    if colors.dtype == np.uint8:
        return colors
    is_float = np.issubdtype(colors.dtype, np.floating)
    colors = colors.astype(np.float64)
    if not np.isfinite(colors).all():
        raise InputError(f"{what}: colours hold NaN or inf; give RGB in 0-255 or 0-1")
    if is_float and colors.size and colors.max() <= 1.0:
        colors = colors * 255.0
    return np.clip(np.round(colors), 0, 255).astype(np.uint8)


def _unit_normals(normals: np.ndarray) -> np.ndarray:
    normals = np.asarray(normals, dtype=np.float64)
    norm = np.linalg.norm(normals, axis=1, keepdims=True)
    return np.divide(normals, norm, out=np.zeros_like(normals), where=norm > 0)


def _header(path: Path, end: bytes, limit: int = 1 << 16) -> list[str] | None:
    """The text lines of a file's header up to and including the line starting with ``end``, or None."""
    with open(path, "rb") as f:
        head = f.read(limit)
    lines = []
    for raw in head.split(b"\n"):
        line = raw.decode("latin-1").strip()
        lines.append(line)
        if raw.strip().startswith(end):
            return lines
    return None


def _ply_counts(path: Path) -> tuple[int, int]:
    """(vertices, faces) declared in a PLY header; faces decide whether it is a mesh."""
    lines = _header(path, b"end_header")
    if not lines or lines[0] != "ply":
        raise InputError(f"cannot read {path}: not a PLY file (no 'ply' ... 'end_header' header)")
    counts = {"vertex": 0, "face": 0}
    for line in lines:
        parts = line.split()
        if len(parts) == 3 and parts[0] == "element" and parts[1] in counts and parts[2].isdigit():
            counts[parts[1]] = int(parts[2])
    return counts["vertex"], counts["face"]


def _pcd_count(path: Path) -> int:
    lines = _header(path, b"DATA")
    if not lines:
        raise InputError(f"cannot read {path}: not a PCD file (no DATA line in its header)")
    for line in lines:
        parts = line.split()
        if len(parts) == 2 and parts[0] == "POINTS" and parts[1].isdigit():
            return int(parts[1])
    raise InputError(f"cannot read {path}: its PCD header has no POINTS count")


def _read_ply_points(path: Path, declared: int) -> PointCloud:
    """A PLY point cloud: binary vertex-only files with numpy (:mod:`cuboidcli.io.ply`), others with
    Open3D."""
    try:
        read = read_ply_vertices(path)
    except ValueError as e:
        raise InputError(f"cannot read {path}: {e}") from e
    if read is None:
        return _read_o3d_points(path, declared)
    points, colors, normals = read
    colors = _colors_u8(colors, str(path)) if colors is not None else None
    return PointCloud(points, colors, normals)


def _read_o3d_points(path: Path, declared: int) -> PointCloud:
    import open3d as o3d

    # Open3D reports a corrupt file on stdout and returns an empty cloud instead of raising.
    with o3d.utility.VerbosityContextManager(o3d.utility.VerbosityLevel.Error):
        pcd = o3d.io.read_point_cloud(str(path))
    points = np.asarray(pcd.points, dtype=np.float64)
    if declared > 0 and len(points) == 0:
        raise InputError(f"cannot read {path}: the file is corrupt or truncated ({declared} points declared)")
    colors = _colors_u8(np.asarray(pcd.colors), str(path)) if pcd.has_colors() else None
    normals = np.asarray(pcd.normals, dtype=np.float64).copy() if pcd.has_normals() else None
    return PointCloud(points, colors, normals)


def _load_trimesh(path: Path):
    import trimesh

    try:
        return trimesh.load(str(path), process=False)
    except Exception as e:  # trimesh's loaders raise many kinds of errors for corrupt files
        raise InputError(f"cannot read {path}: {_one_line(e)}") from e


def _mesh_parts(loaded) -> list[tuple[np.ndarray, np.ndarray, np.ndarray | None]]:
    """(vertices (V, 3), faces (F, 3), colours of each face's corners (F, 3, 3) uint8 or None) of every
    mesh in a trimesh object, node transforms applied (a Scene's instances each once)."""
    import trimesh

    if isinstance(loaded, trimesh.Trimesh):
        instances = [(np.eye(4), loaded)]
    elif isinstance(loaded, trimesh.Scene):
        instances = []
        for node in loaded.graph.nodes_geometry:
            transform, name = loaded.graph[node]
            geom = loaded.geometry.get(name)
            if isinstance(geom, trimesh.Trimesh):
                instances.append((np.asarray(transform, dtype=np.float64), geom))
    else:
        instances = []
    parts = []
    for transform, mesh in instances:
        vertices = np.asarray(mesh.vertices, dtype=np.float64) @ transform[:3, :3].T + transform[:3, 3]
        faces = np.asarray(mesh.faces, dtype=np.int64).reshape(-1, 3)
        visual = mesh.visual
        if visual.kind == "texture":
            try:
                visual = visual.to_color()  # samples the texture image at each vertex's UV
            except Exception:  # a material without an image or UVs: no colour rather than no scene
                visual = None
        kind, corners = getattr(visual, "kind", None), None
        if kind == "vertex":
            corners = np.asarray(visual.vertex_colors)[:, :3].astype(np.uint8)[faces]
        elif kind == "face":
            corners = np.repeat(np.asarray(visual.face_colors)[:, None, :3].astype(np.uint8), 3, axis=1)
        parts.append((vertices, faces, corners))
    return parts


def sample_mesh(
    vertices: np.ndarray, faces: np.ndarray, n: int, seed: int = 0, corner_colors: np.ndarray | None = None
) -> tuple[np.ndarray, np.ndarray | None, np.ndarray]:
    """``n`` points uniformly by area on a triangle mesh: (points (n, 3), colours (n, 3) uint8 or None,
    unit face normals (n, 3)). ``vertices`` (V, 3) in any unit, ``faces`` (F, 3) indices, ``corner_colors``
    (F, 3, 3) the colour at each face corner, interpolated. Deterministic for ``seed``."""
    tri = vertices[faces]
    cross = np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0])
    double_area = np.linalg.norm(cross, axis=1)
    cum = np.cumsum(double_area)
    rng = np.random.default_rng(seed)
    # Searching the cumulative area keeps zero-area faces from ever being drawn.
    face = np.searchsorted(cum, rng.random(n) * cum[-1], side="right").clip(0, len(faces) - 1)
    r1, r2 = rng.random((2, n))
    s = np.sqrt(r1)
    bary = np.stack([1.0 - s, s * (1.0 - r2), s * r2], axis=1)
    points = np.einsum("nk,nkd->nd", bary, tri[face])
    normals = cross[face] / double_area[face, None]
    colors = None
    if corner_colors is not None:
        mixed = np.einsum("nk,nkd->nd", bary, corner_colors[face].astype(np.float64))
        colors = np.clip(np.round(mixed), 0, 255).astype(np.uint8)
    return points, colors, normals


def _read_mesh(path: Path, loaded, n: int, seed: int) -> PointCloud:
    parts = _mesh_parts(loaded)
    parts = [p for p in parts if len(p[1])]
    if not parts:
        raise InputError(
            f"{path} holds no mesh faces; give a mesh with faces, or the points as .ply, .pcd, .npy or .npz"
        )
    offsets = np.cumsum([0] + [len(p[0]) for p in parts])
    vertices = np.concatenate([p[0] for p in parts])
    faces = np.concatenate([p[1] + off for p, off in zip(parts, offsets[:-1], strict=True)])
    bad = int((~np.isfinite(vertices).all(axis=1)).sum())
    if bad:
        raise InputError(f"{path}: {bad} of {len(vertices)} mesh vertices have NaN or inf coordinates")
    if faces.min() < 0 or faces.max() >= len(vertices):
        raise InputError(f"{path}: faces index vertices that do not exist (corrupt mesh)")
    corners = None
    if any(p[2] is not None for p in parts):
        grey = [np.full((len(p[1]), 3, 3), _GREY, np.uint8) for p in parts]
        corners = np.concatenate([p[2] if p[2] is not None else g for p, g in zip(parts, grey, strict=True)])
    tri = vertices[faces]
    area = 0.5 * float(np.linalg.norm(np.cross(tri[:, 1] - tri[:, 0], tri[:, 2] - tri[:, 0]), axis=1).sum())
    if not area > 0.0:
        raise InputError(f"{path}: the mesh has zero surface area ({len(faces)} degenerate faces)")
    points, colors, normals = sample_mesh(vertices, faces, n, seed, corners)
    cloud = PointCloud(points, colors, normals)
    cloud.meta.update(raw_points=len(vertices), faces=len(faces), surface_area=area, mesh_sampled=True)
    return cloud


def _read_array(path: Path) -> PointCloud:
    magic = b"\x93NUMPY" if path.suffix.lower() == ".npy" else b"PK"  # an .npz is a zip archive
    with open(path, "rb") as f:
        if f.read(len(magic)) != magic:
            raise InputError(f"cannot read {path}: not a NumPy {path.suffix.lower()} file")
    try:
        if path.suffix.lower() == ".npy":
            arr = np.load(path, allow_pickle=False)
            if arr.ndim != 2 or arr.shape[1] not in (3, 6):
                raise InputError(
                    f"{path} holds an array of shape {arr.shape}; give (N, 3) xyz or (N, 6) xyz + rgb"
                )
            return PointCloud(arr[:, :3], _colors_u8(arr[:, 3:], str(path)) if arr.shape[1] == 6 else None)
        with np.load(path, allow_pickle=False) as z:
            arrays = {k: z[k] for k in z.files}
    except InputError:
        raise
    except (ValueError, OSError, EOFError, zipfile.BadZipFile) as e:
        raise InputError(f"cannot read {path}: {_one_line(e)}") from e
    key = "points" if "points" in arrays else "xyz" if "xyz" in arrays else None
    if key is None:
        raise InputError(
            f"{path} has no 'points' (or 'xyz') array (it has: {', '.join(arrays) or 'nothing'}); "
            "save it as np.savez(f, points=xyz, colors=rgb, normals=n)"
        )
    points = arrays[key]
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"{path}: '{key}' has shape {points.shape}; give (N, 3) coordinates")
    extra = {}
    for name, keys in (("colors", ("colors", "rgb")), ("normals", ("normals",))):
        found = next((k for k in keys if k in arrays), None)
        if found is not None:
            if arrays[found].shape != points.shape:
                raise InputError(
                    f"{path}: '{found}' has shape {arrays[found].shape} but '{key}' has {points.shape}; "
                    "they must match"
                )
            extra[name] = arrays[found]
    colors = _colors_u8(extra["colors"], str(path)) if "colors" in extra else None
    return PointCloud(points, colors, extra.get("normals"))


def read_scan(path: str | os.PathLike, *, mesh_points: int = 200_000, seed: int = 0) -> PointCloud:
    """A point cloud or mesh file as a :class:`PointCloud` in the file's own coordinates, as stored.

    Meshes (``.obj``, ``.glb``, ``.gltf``, a ``.ply`` with faces) are sampled to ``mesh_points`` points
    uniformly by area with the face normals and the vertex or face colours; ``seed`` makes it repeatable.
    ``meta``: ``path``, ``format``, ``raw_points`` (the file's points or a mesh's vertices) and
    ``mesh_sampled``; a mesh's ``faces``, ``surface_area`` (square file units), ``mesh_points`` and
    ``seed``.
    """
    path = Path(path)
    if not path.exists():
        raise InputError(f"scan file not found: {path}")
    if not path.is_file():
        raise InputError(f"scan path is not a file: {path}")
    suffix = path.suffix.lower()
    if suffix not in SCAN_SUFFIXES:
        raise InputError(
            f"{path.name}: unsupported scan format {suffix or '(none)'}; give one of: "
            + ", ".join(SCAN_SUFFIXES)
        )
    if mesh_points < MIN_POINTS:
        raise InputError(f"mesh_points = {mesh_points}: sample at least {MIN_POINTS} points from a mesh")
    if suffix == ".ply":
        vertices, faces = _ply_counts(path)
        if faces > 0:
            fmt, cloud = "ply-mesh", _read_mesh(path, _load_trimesh(path), mesh_points, seed)
        else:
            fmt, cloud = "ply-points", _read_ply_points(path, vertices)
    elif suffix == ".pcd":
        fmt, cloud = "pcd", _read_o3d_points(path, _pcd_count(path))
    elif suffix in MESH_SUFFIXES:
        fmt, cloud = suffix[1:], _read_mesh(path, _load_trimesh(path), mesh_points, seed)
    else:
        fmt, cloud = suffix[1:], _read_array(path)
    if not np.issubdtype(np.asarray(cloud.points).dtype, np.number):
        raise InputError(f"{path}: coordinates have type {np.asarray(cloud.points).dtype}; give numbers")
    cloud.points = np.asarray(cloud.points, dtype=np.float64)
    if cloud.normals is not None:
        cloud.normals = _unit_normals(cloud.normals)
    meta = {"path": str(path), "format": fmt, "raw_points": len(cloud.points), "mesh_sampled": False}
    meta.update(cloud.meta)
    if meta["mesh_sampled"]:
        meta.update(mesh_points=int(mesh_points), seed=int(seed))
    cloud.meta = meta
    return cloud

"""The numpy reader of binary PLY point clouds against Open3D's, and what it leaves to Open3D."""

from pathlib import Path

import numpy as np
import pytest

from cuboidcli.io import scan
from cuboidcli.io.depth import InputError
from cuboidcli.io.ply import read_ply_vertices
from cuboidcli.io.scan import read_scan


def _arrays(n=500, seed=3):
    rng = np.random.default_rng(seed)
    points = rng.normal(size=(n, 3)) * [2.0, 1.5, 1.0]
    colors = rng.integers(0, 256, (n, 3)).astype(np.uint8)
    normals = rng.normal(size=(n, 3))
    return points, colors, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def _write(path: Path, fmt: str, props: list[tuple[str, str, np.ndarray]], extra_header: str = "") -> Path:
    """A vertex-only PLY written by hand: ``props`` (type, name, column values)."""
    n = len(props[0][2])
    header = f"ply\nformat {fmt} 1.0\ncomment made by a test\n{extra_header}element vertex {n}\n"
    header += "".join(f"property {t} {name}\n" for t, name, _ in props) + "end_header\n"
    types = {"float": "f4", "double": "f8", "uchar": "u1", "ushort": "u2", "int": "i4"}
    if fmt == "ascii":
        rows = np.stack([np.asarray(v, dtype=np.float64) for _, _, v in props], axis=1)
        body = "".join(" ".join(f"{x:.9g}" for x in row) + "\n" for row in rows).encode()
    else:
        order = "<" if fmt == "binary_little_endian" else ">"
        rec = np.empty(n, dtype=[(name, order + types[t]) for t, name, _ in props])
        for _, name, v in props:
            rec[name] = v
        body = rec.tobytes()
    path.write_bytes(header.encode() + body)
    return path


def _props(points, colors=None, normals=None, coord="float"):
    props = [(coord, k, points[:, i]) for i, k in enumerate("xyz")]
    if normals is not None:
        props += [("float", k, normals[:, i]) for i, k in enumerate(("nx", "ny", "nz"))]
    if colors is not None:
        props += [("uchar", k, colors[:, i]) for i, k in enumerate(("red", "green", "blue"))]
    return props


@pytest.mark.parametrize("fmt", ["binary_little_endian", "binary_big_endian"])
@pytest.mark.parametrize("coord", ["float", "double"])
def test_binary_vertices_read_as_open3d_reads_them(tmp_path, fmt, coord):
    points, colors, normals = _arrays()
    path = _write(tmp_path / "c.ply", fmt, _props(points, colors, normals, coord))
    points_np, colors_np, normals_np = read_ply_vertices(path)
    ours = read_scan(path)
    theirs = scan._read_o3d_points(path, len(points))
    want = points.astype(np.float32 if coord == "float" else np.float64).astype(np.float64)
    assert np.array_equal(points_np, want) and np.array_equal(ours.points, theirs.points)
    assert colors_np.dtype == np.uint8 and np.array_equal(colors_np, colors)
    assert np.array_equal(ours.colors, theirs.colors) and np.array_equal(ours.colors, colors)
    assert np.allclose(ours.normals, theirs.normals, atol=1e-12)
    assert np.allclose(normals_np, normals, atol=1e-6)


def test_properties_in_any_order_with_extra_ones(tmp_path):
    points, colors, normals = _arrays(n=50)
    props = _props(points, colors)[::-1] + [
        ("ushort", "intensity", np.arange(50)),
        ("uchar", "alpha", colors[:, 0]),
    ]
    points_np, colors_np, normals_np = read_ply_vertices(
        _write(tmp_path / "c.ply", "binary_little_endian", props)
    )
    assert np.array_equal(points_np, points.astype(np.float32)) and np.array_equal(colors_np, colors)
    assert normals_np is None
    bare = read_ply_vertices(_write(tmp_path / "b.ply", "binary_little_endian", _props(points)))
    assert bare[1] is None and bare[2] is None


def test_other_layouts_are_left_to_open3d(tmp_path):
    points, colors, _ = _arrays(n=40)
    ascii_path = _write(tmp_path / "a.ply", "ascii", _props(points, colors))
    assert read_ply_vertices(ascii_path) is None
    cloud = read_scan(ascii_path)  # through Open3D
    assert np.allclose(cloud.points, points, atol=1e-5) and np.array_equal(cloud.colors, colors)
    before = _write(
        tmp_path / "m.ply", "binary_little_endian", _props(points), "element camera 0\nproperty float f\n"
    )
    assert read_ply_vertices(before) is None
    listed = tmp_path / "l.ply"
    head = "ply\nformat binary_little_endian 1.0\nelement vertex 1\n"
    listed.write_bytes((head + "property float x\nproperty list uchar int idx\nend_header\n").encode())
    assert read_ply_vertices(listed) is None


def test_vertices_without_z_are_one_line_naming_what_is_missing(tmp_path):
    points, _, _ = _arrays(n=40)
    no_z = _write(tmp_path / "z.ply", "binary_little_endian", _props(points)[:2])
    with pytest.raises(ValueError, match=r"its vertices have no z \(properties: x, y\)"):
        read_ply_vertices(no_z)
    with pytest.raises(InputError, match=r"cannot read .*z\.ply: its vertices have no z"):
        read_scan(no_z)


def test_a_truncated_file_is_one_line_naming_the_counts(tmp_path):
    points, _, _ = _arrays(n=100)
    path = _write(tmp_path / "c.ply", "binary_little_endian", _props(points))
    path.write_bytes(path.read_bytes()[:-13])  # 12 bytes a point: 98 whole points remain
    with pytest.raises(ValueError, match="100 points declared, 98 stored"):
        read_ply_vertices(path)
    with pytest.raises(InputError, match=r"cannot read .*c\.ply: the file is truncated"):
        read_scan(path)


def test_elements_after_the_vertices_are_ignored(tmp_path):
    points, _, _ = _arrays(n=30)
    path = _write(tmp_path / "c.ply", "binary_little_endian", _props(points))
    data = path.read_bytes().replace(b"end_header\n", b"element extra 0\nproperty float q\nend_header\n")
    path.write_bytes(data)
    assert np.array_equal(read_ply_vertices(path)[0], points.astype(np.float32))

"""A room fitted on the CPU with the default parts never imports torch, like a frame
(tests/cli/test_fit_cli.py::test_a_default_frame_fit_never_imports_torch): the room's scoring kernels are
numba loops, and its points are numpy arrays unless a part computes with torch. Nor Open3D: a binary PLY
point cloud is read with numpy and the normals are numba loops."""

from __future__ import annotations

import json

import numpy as np

from tests.cli.test_fit_cli import _modules_loaded_by, _python_prints
from tests.fitting.test_room_fit import scanned_room


def write_ply(path, points: np.ndarray, colors: np.ndarray) -> None:
    """A binary little-endian PLY of points (N, 3) float32 with colours (N, 3) uint8, as scanners write."""
    header = (
        "ply\nformat binary_little_endian 1.0\n"
        f"element vertex {len(points)}\n"
        "property float x\nproperty float y\nproperty float z\n"
        "property uchar red\nproperty uchar green\nproperty uchar blue\nend_header\n"
    )
    rows = np.empty(len(points), dtype=[("p", "<f4", 3), ("c", "u1", 3)])
    rows["p"], rows["c"] = points, colors
    with open(path, "wb") as f:
        f.write(header.encode("ascii"))
        f.write(rows.tobytes())


def test_a_default_room_fit_never_imports_torch_or_open3d(tmp_path):
    """A scan fitted with the defaults (sequential sampler, numerical solver, the room's numba kernels) runs
    without torch or Open3D, in the command and in the Python API, and says it drew from numpy's
    generator."""
    pts = scanned_room()
    rgb = np.random.default_rng(0).integers(0, 256, pts.shape).astype(np.uint8)
    scan = tmp_path / "room.ply"
    write_ply(scan, pts, rgb)
    out = tmp_path / "room.json"
    assert (
        _modules_loaded_by(["fit", str(scan), "-o", str(out), "--voxel", "0.1", "-q"], ("torch", "open3d"))
        == []
    )
    d = json.loads(out.read_text())
    assert d["frame"] == "world" and "floor" in [c["kind"] for c in d["cuboids"]] and d["objects"]
    assert d["settings"]["random_generator"] == "numpy" and d["settings"]["backend_used"] == "room"
    api = (
        "import sys, cuboidcli as cb\n"
        f"r = cb.Fitter(voxel_m=0.1).fit({str(scan)!r})\n"
        "assert r.cuboids and r.info.kind == 'room'\n"
        "print(sorted(m for m in sys.modules if m.startswith(('torch', 'open3d'))))\n"
    )
    assert _python_prints(api) == "[]"

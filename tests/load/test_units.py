"""A room's file is read as stored and made metres by its ``--unit`` (load.units.in_metres, through
load.room.load_room); every room, a file, points in memory or a fused sequence, is checked to be one: enough
finite points, room-sized, each refusal one line that names the unit the coordinates probably are in."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.io.depth import InputError
from cuboidcli.io.scan import PointCloud, read_scan
from cuboidcli.load.room import load_room, points_room
from cuboidcli.load.units import UNITS, check_cloud, in_metres
from tests.conftest import SHARED_DATA
from tests.io.test_scan import EXTENTS, box, cloud_arrays
from tests.io.test_sequence import refused as refused_call


def refused(path, *fragments, **kwargs) -> str:
    """The one-line message that refuses ``load_room(path, **kwargs)``, holding each fragment."""
    return refused_call(lambda: load_room(path, **kwargs), *fragments)


def test_units_scale(tmp_path):
    points = cloud_arrays()[0]
    np.save(tmp_path / "cm.npy", points * 100)
    np.save(tmp_path / "mm.npy", points * 1000)
    assert np.allclose(load_room(tmp_path / "cm.npy", unit="cm").cloud.points, points)
    assert np.allclose(load_room(tmp_path / "mm.npy", unit="mm").cloud.points, points)
    box(extents=EXTENTS * 100).export(tmp_path / "box_cm.obj")
    mesh = in_metres(read_scan(tmp_path / "box_cm.obj", mesh_points=1000), "cm")
    assert np.abs(mesh.points).max() == pytest.approx(2.0) and mesh.meta["unit"] == "cm"
    assert mesh.meta["surface_area_m2"] == pytest.approx(18.0) and "surface_area" not in mesh.meta
    assert list(mesh.meta) == [
        "path", "format", "unit", "raw_points", "mesh_sampled", "faces", "surface_area_m2", "mesh_points",
        "seed", "points", "diagonal_m",
    ]  # fmt: skip
    assert set(UNITS) == {"m", "cm", "mm"}


def test_unusable_rooms(tmp_path):
    refused(tmp_path / "room.npy", "not found")
    np.save(tmp_path / "room.npy", cloud_arrays()[0])
    refused(tmp_path / "room.npy", "unknown unit", "m, cm, mm", unit="ft")
    np.save(tmp_path / "ten.npy", cloud_arrays(10)[0])
    refused(tmp_path / "ten.npy", "has 10 points", "at least 100")
    header = [
        "ply",
        "format ascii 1.0",
        "element vertex 0",
        *(f"property float {c}" for c in "xyz"),
        "end_header",
    ]
    (tmp_path / "empty.ply").write_text("\n".join(header) + "\n")
    refused(tmp_path / "empty.ply", "has 0 points")
    nan = cloud_arrays()[0]
    nan[[3, 7, 9]] = [np.nan, 0, np.inf]
    np.save(tmp_path / "nan.npy", nan)
    refused(tmp_path / "nan.npy", "3 of 500 points", "NaN")
    with pytest.raises(InputError, match="array has 50 points; a room needs at least 100"):
        points_room(cloud_arrays(50)[0])


def test_implausible_scale(tmp_path):
    points = cloud_arrays()[0]
    np.save(tmp_path / "mm.npy", points * 1000)
    np.save(tmp_path / "cm.npy", points * 100)
    np.save(tmp_path / "tiny.npy", points / 1000)
    refused(tmp_path / "mm.npy", "millimetres", "--unit mm")
    refused(tmp_path / "cm.npy", "centimetres", "--unit cm")
    refused(tmp_path / "tiny.npy", "too small for a room", "check --unit (coordinates read as metres)")
    np.save(tmp_path / "metres.npy", points)
    refused(tmp_path / "metres.npy", "too small for a room", "it looks like metres: pass --unit m", unit="mm")
    np.save(tmp_path / "room_7m.npy", points * 7.0 / np.linalg.norm(np.ptp(points, axis=0)))  # 7 m across
    refused(tmp_path / "room_7m.npy", "70.0 mm across with --unit cm", "pass --unit m", unit="cm")
    np.save(tmp_path / "km.npy", points * 1000 * 1000)
    assert "too large for a room; check --unit" in refused(tmp_path / "km.npy")
    with pytest.raises(InputError, match="it looks like centimetres: pass --unit cm"):
        points_room(points * 100)


def test_check_cloud_on_a_built_cloud():
    points, _, normals = cloud_arrays()
    normals[0] = 0.0
    cloud = check_cloud(PointCloud(points, normals=normals, meta={"path": "fused"}), "m")
    assert cloud.normals is None and "1 of 500 normals" in cloud.warnings[0]
    assert cloud.meta["points"] == 500 and 0 < cloud.meta["diagonal_m"] < 6
    with pytest.raises(InputError, match="fused has 50 points"):
        check_cloud(PointCloud(points[:50], meta={"path": "fused"}), "m")


@pytest.mark.parametrize("name", ["livingroom_fragment.pcd", "frag_115.ply"])
def test_real_scan_fragments_are_rooms(name):
    path = SHARED_DATA / "scans" / name
    if not path.is_file():
        pytest.skip(f"{path} is absent (shared data is not part of the repository)")
    room = load_room(path)
    assert room.meta["unit"] == "m" and 0.5 < room.meta["diagonal_m"] < 10.0 and room.meta["warnings"] == []
    assert room.cloud.normals is not None

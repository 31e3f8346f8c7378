"""Point clouds and meshes read into one PointCloud: meshes sampled by area on their surface, colours and
normals kept, coordinates as the file stores them, every bad file a one-line InputError; the real scan
fragments when present. Units and the room checks are the loader's (tests/load/test_units.py)."""

import json

import numpy as np
import pytest

from cuboidcli.io.depth import InputError
from cuboidcli.io.scan import SCAN_SUFFIXES, is_scan_file, read_scan
from tests.conftest import SHARED_DATA

EXTENTS = np.array([1.0, 1.0, 4.0])  # the +z face has a quarter of the +x face's area


def box(colour=None, extents=EXTENTS):
    import trimesh

    mesh = trimesh.creation.box(extents=extents)
    if colour is not None:
        mesh.visual.vertex_colors = [*colour, 255]
    return mesh


def surface_distance(points, extents=EXTENTS, centre=(0.0, 0.0, 0.0)):
    """Distance of points inside or on an axis-aligned box to its surface."""
    inside = extents / 2 - np.abs(points - np.asarray(centre))
    return np.abs(inside).min(axis=1), inside.min(axis=1)


def cloud_arrays(n=500, seed=1):
    rng = np.random.default_rng(seed)
    points = rng.uniform([0, 0, 0], [4.0, 3.0, 2.5], (n, 3))
    colors = rng.integers(0, 256, (n, 3), dtype=np.uint8)
    normals = rng.normal(size=(n, 3))
    return points, colors, normals / np.linalg.norm(normals, axis=1, keepdims=True)


def write_o3d(path, points, colors=None, normals=None):
    import open3d as o3d

    pcd = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    if colors is not None:
        pcd.colors = o3d.utility.Vector3dVector(colors / 255.0)
    if normals is not None:
        pcd.normals = o3d.utility.Vector3dVector(normals)
    assert o3d.io.write_point_cloud(str(path), pcd)
    return path


def refused(path, *fragments, **kwargs) -> str:
    with pytest.raises(InputError) as info:
        read_scan(path, **kwargs)
    message = str(info.value)
    assert "\n" not in message and message.strip() == message
    for fragment in fragments:
        assert fragment in message, message
    return message


@pytest.mark.parametrize("suffix", [".ply", ".obj", ".glb"])
def test_mesh_sampled_on_surface_by_area(tmp_path, suffix):
    path = tmp_path / f"box{suffix}"
    box(colour=(200, 30, 10)).export(path)
    cloud = read_scan(path, mesh_points=20_000)
    assert cloud.points.shape == (20_000, 3) and cloud.points.dtype == np.float64
    distance, inside = surface_distance(cloud.points)
    assert distance.max() < 1e-6 and inside.min() > -1e-6
    on_z = np.abs(cloud.points[:, 2] - 2.0) < 1e-6
    on_x = np.abs(cloud.points[:, 0] - 0.5) < 1e-6
    assert 3.5 < on_x.sum() / on_z.sum() < 4.5  # 4x the area, about 4x the points
    assert (cloud.colors == [200, 30, 10]).all()
    assert np.allclose(cloud.normals[on_z], [0, 0, 1]) and np.allclose(cloud.normals[on_x], [1, 0, 0])
    assert cloud.meta["mesh_sampled"] and cloud.meta["raw_points"] == 8 and cloud.meta["faces"] == 12
    assert cloud.meta["format"] == {".ply": "ply-mesh", ".obj": "obj", ".glb": "glb"}[suffix]
    assert cloud.viewpoints is None and cloud.frames is None and cloud.frame_names == []
    json.dumps(cloud.meta)


def test_scene_node_transforms_and_determinism(tmp_path):
    import trimesh

    scene = trimesh.Scene()
    scene.add_geometry(box(), transform=trimesh.transformations.translation_matrix([5.0, 0.0, 0.0]))
    scene.add_geometry(box(), transform=trimesh.transformations.translation_matrix([-5.0, 0.0, 0.0]))
    scene.export(tmp_path / "two.glb")
    a = read_scan(tmp_path / "two.glb", mesh_points=4000, seed=3)
    b = read_scan(tmp_path / "two.glb", mesh_points=4000, seed=3)
    c = read_scan(tmp_path / "two.glb", mesh_points=4000, seed=4)
    assert np.array_equal(a.points, b.points) and not np.array_equal(a.points, c.points)
    right = a.points[:, 0] > 0
    assert 0.45 < right.mean() < 0.55
    assert surface_distance(a.points[right], centre=(5, 0, 0))[0].max() < 1e-6
    assert surface_distance(a.points[~right], centre=(-5, 0, 0))[0].max() < 1e-6
    assert a.colors is None  # no colours in the file: none invented


def test_face_colours_and_uncoloured_parts(tmp_path):
    import trimesh

    mesh = box()
    colours = np.tile([0, 0, 255, 255], (len(mesh.faces), 1))
    colours[mesh.triangles_center[:, 0] > 0.49] = [255, 0, 0, 255]
    mesh.visual.face_colors = colours
    mesh.export(tmp_path / "faces.ply")
    cloud = read_scan(tmp_path / "faces.ply", mesh_points=2000)
    on_x = np.abs(cloud.points[:, 0] - 0.5) < 1e-6
    assert (cloud.colors[on_x] == [255, 0, 0]).all() and (cloud.colors[~on_x] == [0, 0, 255]).all()
    scene = trimesh.Scene([box(colour=(0, 255, 0))])
    scene.add_geometry(box(), transform=trimesh.transformations.translation_matrix([3.0, 0.0, 0.0]))
    scene.export(tmp_path / "mixed.glb")
    cloud = read_scan(tmp_path / "mixed.glb", mesh_points=2000)
    right = cloud.points[:, 0] > 2.0
    assert (cloud.colors[~right] == [0, 255, 0]).all() and (cloud.colors[right] == 128).all()  # grey


@pytest.mark.parametrize("suffix", [".pcd", ".ply"])
def test_points_round_trip_colours_and_normals(tmp_path, suffix):
    points, colors, normals = cloud_arrays()
    cloud = read_scan(write_o3d(tmp_path / f"c{suffix}", points, colors, normals))
    assert cloud.meta["format"] == {".pcd": "pcd", ".ply": "ply-points"}[suffix]
    assert not cloud.meta["mesh_sampled"] and cloud.meta["raw_points"] == len(points)
    assert np.allclose(cloud.points, points, atol=1e-5)
    assert cloud.colors.dtype == np.uint8 and np.array_equal(cloud.colors, colors)
    assert cloud.normals.dtype == np.float64 and np.allclose(cloud.normals, normals, atol=1e-5)
    bare = read_scan(write_o3d(tmp_path / f"bare{suffix}", points))
    assert bare.colors is None and bare.normals is None


def test_arrays(tmp_path):
    points, colors, normals = cloud_arrays()
    np.save(tmp_path / "xyz.npy", points)
    np.save(tmp_path / "rgb255.npy", np.hstack([points, colors.astype(float)]))
    np.save(tmp_path / "rgb01.npy", np.hstack([points, colors / 255.0]))
    np.savez(tmp_path / "all.npz", xyz=points, rgb=colors, normals=normals * 3.0)
    assert read_scan(tmp_path / "xyz.npy").colors is None
    for name in ("rgb255.npy", "rgb01.npy", "all.npz"):
        cloud = read_scan(tmp_path / name)
        assert np.allclose(cloud.points, points) and np.array_equal(cloud.colors, colors), name
    assert np.allclose(read_scan(tmp_path / "all.npz").normals, normals)  # made unit length
    assert read_scan(tmp_path / "xyz.npy").meta["format"] == "npy"


def test_coordinates_as_stored(tmp_path):
    """The reader knows no units: a file in centimetres reads in centimetres, a mesh's surface area in
    square file units; nothing is checked for being a room (a tiny, a huge or a NaN cloud reads)."""
    points = cloud_arrays()[0]
    np.save(tmp_path / "cm.npy", points * 100)
    assert np.array_equal(read_scan(tmp_path / "cm.npy").points, points * 100)
    box(extents=EXTENTS * 100).export(tmp_path / "box_cm.obj")
    mesh = read_scan(tmp_path / "box_cm.obj", mesh_points=1000)
    assert np.abs(mesh.points).max() == pytest.approx(200.0) and "unit" not in mesh.meta
    assert mesh.meta["surface_area"] == pytest.approx(180_000.0)
    assert list(mesh.meta) == [
        "path", "format", "raw_points", "mesh_sampled", "faces", "surface_area", "mesh_points", "seed",
    ]  # fmt: skip
    nan = points.copy()
    nan[3] = np.nan
    np.save(tmp_path / "odd.npy", nan[:10] * 1e6)
    assert len(read_scan(tmp_path / "odd.npy")) == 10


def test_is_scan_file():
    assert all(is_scan_file(f"room{s.upper()}") for s in SCAN_SUFFIXES)
    assert not is_scan_file("depth.png") and not is_scan_file("folder")


def test_bad_inputs(tmp_path):
    refused(tmp_path / "missing.ply", "not found")
    refused(tmp_path, "not a file")
    (tmp_path / "room.xyz").write_text("1 2 3\n")
    refused(tmp_path / "room.xyz", "unsupported", ".pcd", ".npz")
    for name in ("junk.ply", "junk.pcd", "junk.glb", "junk.npy", "junk.npz"):
        (tmp_path / name).write_bytes(b"\x00garbage\xff" * 20)
        refused(tmp_path / name, "cannot read")
    good = write_o3d(tmp_path / "good.pcd", cloud_arrays()[0])
    (tmp_path / "cut.pcd").write_bytes(good.read_bytes()[:-3000])
    refused(tmp_path / "cut.pcd", "corrupt")
    np.save(tmp_path / "four.npy", np.zeros((500, 4)))
    refused(tmp_path / "four.npy", "(500, 4)", "(N, 3)")
    np.save(tmp_path / "flat.npy", np.zeros(500))
    refused(tmp_path / "flat.npy", "(500,)")
    np.savez(tmp_path / "nokey.npz", pts=cloud_arrays()[0])
    refused(tmp_path / "nokey.npz", "'points'", "pts")
    np.savez(tmp_path / "mismatch.npz", points=cloud_arrays()[0], colors=np.zeros((5, 3)))
    refused(tmp_path / "mismatch.npz", "'colors'", "must match")
    (tmp_path / "verts.obj").write_text("v 0 0 0\nv 1 0 0\nv 0 1 0\n")
    refused(tmp_path / "verts.obj", "no mesh faces")
    (tmp_path / "flat.obj").write_text("v 0 0 0\nv 1 0 0\nv 2 0 0\nf 1 2 3\nf 1 3 2\n")
    refused(tmp_path / "flat.obj", "zero surface area")
    box().export(tmp_path / "box.obj")
    refused(tmp_path / "box.obj", "at least 100", mesh_points=10)


REAL = [("livingroom_fragment.pcd", "pcd", 113_662), ("frag_115.ply", "ply-mesh", 64_365)]


@pytest.mark.parametrize(("name", "fmt", "count"), REAL)
def test_real_scan_fragments(name, fmt, count):
    path = SHARED_DATA / "scans" / name
    if not path.is_file():
        pytest.skip(f"{path} is absent (shared data is not part of the repository)")
    cloud = read_scan(path, mesh_points=50_000)
    assert cloud.meta["format"] == fmt and cloud.meta["raw_points"] == count
    # frag_115.ply has faces (127,229 triangles on its 64,365 vertices), so it is read as a mesh.
    assert len(cloud) == (count if fmt == "pcd" else 50_000)
    assert cloud.colors is not None and cloud.colors.dtype == np.uint8 and cloud.colors.std() > 5
    assert cloud.normals is not None and np.allclose(np.linalg.norm(cloud.normals, axis=1), 1.0)
    extent = cloud.points.max(axis=0) - cloud.points.min(axis=0)
    assert 0.5 < np.linalg.norm(extent) < 10.0 and cloud.warnings == []

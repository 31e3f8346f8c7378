"""Loading a room at its edges: which files are rooms, the up a sequence's cameras hint (and when they
cancel), arrays and Open3D clouds in memory, the levelled world frame, and which frames saw a cuboid."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.io.depth import InputError
from cuboidcli.io.scan import MIN_POINTS, PointCloud
from cuboidcli.io.sequence import read_sequence
from cuboidcli.load.room import (
    is_room_input,
    load_room,
    parse_up,
    points_room,
    seen_by,
    world_from_input,
)
from tests.io.test_sequence import POSES, pose, write_plain, yaw


def room_points(n: int = 400, seed: int = 0) -> np.ndarray:
    return np.random.default_rng(seed).uniform([0, 0, 0], [4, 3, 2.5], (n, 3))


def test_which_point_arrays_are_rooms(tmp_path):
    np.save(tmp_path / "seven.npy", room_points(7))
    np.save(tmp_path / "six.npy", room_points(6))
    np.save(tmp_path / "coloured.npy", np.c_[room_points(50), np.zeros((50, 3))])
    np.save(tmp_path / "four.npy", np.zeros((50, 4)))
    np.save(tmp_path / "depth.npy", np.ones((48, 64)))
    np.savez(tmp_path / "points.npz", points=room_points())
    np.savez(tmp_path / "xyz.npz", xyz=room_points())
    np.savez(tmp_path / "depth.npz", depth=np.ones((48, 64)))
    (tmp_path / "broken.npy").write_bytes(b"\x93NUMPY garbage")
    (tmp_path / "room.ply").write_text("ply\n")
    (tmp_path / "empty").mkdir()
    rooms = {p.name for p in tmp_path.iterdir() if is_room_input(p)}
    assert rooms == {"seven.npy", "coloured.npy", "points.npz", "xyz.npz", "room.ply"}
    assert not is_room_input(tmp_path / "missing.npy")
    assert is_room_input(write_plain(tmp_path / "seq"))


def test_a_sequence_hints_its_cameras_mean_up(tmp_path):
    room = load_room(write_plain(tmp_path / "level", POSES[:2]))
    assert np.allclose(room.up_hint, [0.0, -1.0, 0.0])  # OpenCV cameras looking along z: up is -y
    assert room.camera is not None and room.meta["n_points"] == len(room.cloud.points)
    # two cameras rolled upside down against each other: their ups cancel and z is taken
    flipped = np.diag([-1.0, -1.0, 1.0])
    cancelled = load_room(write_plain(tmp_path / "cancel", [pose(), pose(flipped, (0.3, 0.0, 0.0))]))
    assert np.allclose(cancelled.up_hint, [0.0, 0.0, 1.0])
    tilted = load_room(write_plain(tmp_path / "tilted", [pose(yaw(0.3)), pose(yaw(0.3), (0.2, 0.0, 0.0))]))
    assert np.linalg.norm(tilted.up_hint) == pytest.approx(1.0)
    with pytest.raises(InputError, match="--every must be at least 1"):
        load_room(tmp_path / "level", every=0)
    assert len(read_sequence(tmp_path / "level").frames) == 2


def test_a_gltf_scan_is_y_up_and_other_files_z_up(tmp_path):
    import trimesh

    box = trimesh.creation.box(extents=(4.0, 2.5, 3.0))
    box.export(tmp_path / "room.glb")
    box.export(tmp_path / "room.obj")
    assert np.allclose(load_room(tmp_path / "room.glb").up_hint, [0.0, 1.0, 0.0])
    assert np.allclose(load_room(tmp_path / "room.obj").up_hint, [0.0, 0.0, 1.0])


def test_points_in_memory_with_colours():
    pts = room_points()
    colours = np.tile([10.4, 300.0, -5.0], (len(pts), 1))
    room = points_room(np.c_[pts, colours])
    assert room.cloud.colors.dtype == np.uint8 and room.cloud.colors[0].tolist() == [10, 255, 0]
    assert np.array_equal(room.cloud.points, pts) and room.meta["path"] is None
    assert np.allclose(room.up_hint, [0.0, 0.0, 1.0]) and room.camera is None
    own = points_room(np.c_[pts, colours], colors=np.full((len(pts), 3), 7))
    assert (own.cloud.colors == 7).all()  # colours given separately win over the array's
    assert points_room(pts).cloud.colors is None
    for bad in (pts[:, :2], np.c_[pts, pts[:, :1]], pts.astype(str), pts[None]):
        with pytest.raises(InputError, match=r"\(N, 3\) or \(N, 6\) array of numbers"):
            points_room(bad)


def test_an_open3d_cloud_in_memory():
    import open3d as o3d

    pts = room_points()
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(pts))
    assert points_room(cloud).cloud.colors is None
    cloud.colors = o3d.utility.Vector3dVector(np.full((len(pts), 3), 0.5))
    room = points_room(cloud)
    assert np.allclose(room.cloud.points, pts) and (room.cloud.colors == 128).all()  # 0.5 of 255, rounded


@pytest.mark.parametrize(
    ("up", "axes"),
    [
        ((0.0, 0.0, 1.0), None),
        ((0.0, 0.0, 2.0), None),
        ((1.0, 0.0, 0.0), None),  # up along the input's x: its y is made horizontal instead
        ((0.1, -0.9, 0.2), None),
        ((0.0, 0.0, 1.0), np.array([[0.0, 0.6, -0.8], [0.0, 0.8, 0.6], [1.0, 0.0, 0.0]])),
    ],
)
def test_the_levelled_world_is_a_rotation_with_z_up(up, axes):
    m = world_from_input(np.array(up), axes)
    r = m[:3, :3]
    assert np.allclose(r @ r.T, np.eye(3)) and np.linalg.det(r) == pytest.approx(1.0)
    assert np.allclose(r @ (np.array(up) / np.linalg.norm(up)), [0.0, 0.0, 1.0])
    assert np.array_equal(m[3], [0.0, 0.0, 0.0, 1.0]) and np.array_equal(m[:3, 3], [0.0, 0.0, 0.0])
    if axes is not None:  # the room's first horizontal axis becomes x
        assert np.allclose(r @ axes[:, 1], [1.0, 0.0, 0.0])
    elif abs(up[0]) < 0.99 * np.linalg.norm(up):
        assert (r @ [1.0, 0.0, 0.0])[1] == pytest.approx(0.0, abs=1e-12)  # x stays in the x-z plane


def test_a_frame_saw_a_cuboid_from_ten_of_its_points():
    n = 3 * MIN_POINTS
    labels = np.full(n, -1)
    frames = np.zeros(n, dtype=np.int32)
    labels[:10] = 0  # cuboid 0: 10 points from frame 1
    frames[:10] = 1
    labels[20:29] = 1  # cuboid 1: 9 points from frame 2, 30 from frame 0
    frames[20:29] = 2
    labels[40:70] = 1
    cloud = PointCloud(room_points(n), frames=frames, frame_names=["a", "b", "c"])
    assert seen_by(cloud, labels, 3) == [["b"], ["a"], []]
    assert seen_by(PointCloud(room_points(n)), labels, 2) == [[], []]  # a bare cloud: no frames


def test_every_up_name_and_unusable_vectors():
    assert [parse_up(n) for n in ("z", "y", "-y", "x")] == [
        (0.0, 0.0, 1.0),
        (0.0, 1.0, 0.0),
        (0.0, -1.0, 0.0),
        (1.0, 0.0, 0.0),
    ]
    for bad in ("nan,0,1", "0,inf,1", "0,0,0", "1,2", "up"):
        with pytest.raises(InputError, match="--up"):
            parse_up(bad)


def test_a_sequence_is_fused_in_2_cm_voxels_and_its_hint_is_a_unit_mean(tmp_path):
    pitch = np.array([[1.0, 0.0, 0.0], [0.0, np.cos(0.5), -np.sin(0.5)], [0.0, np.sin(0.5), np.cos(0.5)]])
    room = load_room(write_plain(tmp_path, [pose(), pose(pitch, (0.2, 0.0, 0.0))]))
    assert room.cloud.meta["voxel_m"] == 0.02
    ups = np.array([[0.0, -1.0, 0.0], pitch @ [0.0, -1.0, 0.0]])
    assert np.allclose(room.up_hint, ups.mean(0) / np.linalg.norm(ups.mean(0)))
    assert 0.0 <= room.load_seconds < 60.0 and room.meta["load_s"] == round(room.load_seconds, 6)


def test_an_object_array_is_not_a_room_and_a_list_of_points_is(tmp_path):
    np.save(tmp_path / "objects.npy", np.empty((10, 3), dtype=object), allow_pickle=True)
    assert not is_room_input(tmp_path / "objects.npy")
    room = points_room(room_points().tolist())
    assert room.cloud.points.shape == (400, 3) and 0.0 <= room.load_seconds < 60.0


def test_the_levelled_world_takes_the_horizontal_part_of_a_tilted_room_axis():
    axes = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.1, 0.0]])  # column 1 leans 5.7 deg towards up
    r = world_from_input(np.array([0.0, 0.0, 1.0]), axes)[:3, :3]
    assert np.allclose(r[0], [1.0, 0.0, 0.0]) and np.allclose(r @ r.T, np.eye(3))

"""Posed RGB-D sequences: the four layouts read, frames fused onto the known world plane z = 2.03 m they were
rendered from, viewpoints the real camera centres, and every bad folder a one-line InputError."""

import json
import math

import cv2
import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.io.depth import InputError
from cuboidcli.io.sequence import read_sequence, sequence_layout
from cuboidcli.load.fuse import fuse_sequence
from tests.conftest import SHARED_DATA, yaw

CAM = Camera(60.0, 60.0, 31.5, 23.5, 64, 48)
PLANE_Z = 2.03  # inside a voxel layer for 2 and 10 cm voxels, so each voxel sees every camera
COLOURS = [(255, 0, 0), (0, 255, 0), (0, 0, 255), (255, 255, 0)]


def pose(rotation=None, centre=(0.0, 0.0, 0.0)) -> np.ndarray:
    m = np.eye(4)
    m[:3, :3] = np.eye(3) if rotation is None else rotation
    m[:3, 3] = centre
    return m


def plane_depth(world_from_camera, cam=CAM) -> np.ndarray:
    """Depth (H, W) metres of the world plane z = PLANE_Z, ray cast exactly; 0 where it is not in view."""
    u, v = cam.pixel_grid()
    rays = np.stack([(u - cam.cx) / cam.fx, (v - cam.cy) / cam.fy, np.ones_like(u)], axis=-1)
    world_z = rays @ world_from_camera[2, :3]  # z of the world direction of each ray (camera z = 1)
    with np.errstate(divide="ignore"):
        depth = (PLANE_Z - world_from_camera[2, 3]) / world_z
    return np.where(world_z > 0.05, depth, 0.0)


def write_png(path, depth_m, scale=0.001):
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.round(depth_m / scale).astype(np.uint16))


def write_rgb(path, colour, shape=(48, 64)):
    path.parent.mkdir(parents=True, exist_ok=True)
    cv2.imwrite(str(path), np.full((*shape, 3), colour[::-1], np.uint8))  # cv2 writes BGR


POSES = [pose(), pose(yaw(0.2), (0.8, 0.0, 0.1)), pose(yaw(-0.1), (-0.4, 0.2, 0.0))]


def write_plain(root, poses=POSES, scale=0.001, camera_extra=None):
    for i, m in enumerate(poses):
        write_png(root / "depth" / f"{i:05d}.png", plane_depth(m), scale)
        write_rgb(root / "color" / f"{i:05d}.png", COLOURS[i])
        (root / "pose").mkdir(exist_ok=True)
        np.savetxt(root / "pose" / f"{i:05d}.txt", m)
    entry = {**CAM.to_dict(), **(camera_extra or {})}
    (root / "cameras.json").write_text(json.dumps({"scene": entry}))
    return root


def refused(call, *fragments) -> str:
    with pytest.raises(InputError) as info:
        call()
    message = str(info.value)
    assert "\n" not in message and message.strip() == message
    for fragment in fragments:
        assert fragment in message, message
    return message


def sees(world_from_camera, points, margin_px=5.0):
    """Which points project inside the image with a margin (+1), clearly outside (-1), or near its border."""
    local = (points - world_from_camera[:3, 3]) @ world_from_camera[:3, :3]
    uv, z = CAM.project(local)
    inner = (uv[:, 0] > margin_px) & (uv[:, 0] < CAM.width - 1 - margin_px)
    inner &= (uv[:, 1] > margin_px) & (uv[:, 1] < CAM.height - 1 - margin_px) & (z > 0)
    outer = (uv[:, 0] < -margin_px) | (uv[:, 0] > CAM.width - 1 + margin_px)
    outer |= (uv[:, 1] < -margin_px) | (uv[:, 1] > CAM.height - 1 + margin_px)
    return np.where(inner, 1, np.where(outer, -1, 0))


def test_plain_fused_on_the_plane_with_nearest_viewpoints(tmp_path):
    seq = read_sequence(write_plain(tmp_path, POSES[:2]))
    assert sequence_layout(tmp_path) == "plain" and seq.layout == "plain" and seq.camera == CAM
    assert [f.name for f in seq.frames] == ["00000", "00001"] and seq.depth_scale == 0.001
    calls = []
    # 10 cm voxels hold about 9 pixels of each camera that sees them (a pixel is 3.3 cm wide at 2 m).
    cloud = fuse_sequence(seq, voxel_m=0.1, progress=lambda done, total: calls.append((done, total)))
    assert calls == [(1, 2), (2, 2)]
    assert np.abs(cloud.points[:, 2] - PLANE_Z).max() < 0.01
    centres = np.array([m[:3, 3] for m in POSES[:2]])
    assert np.array_equal(cloud.viewpoints, centres[cloud.frames]) and cloud.frames.dtype == np.int32
    assert cloud.frame_names == ["00000", "00001"]
    seen = np.stack([sees(m, cloud.points) for m in POSES[:2]], axis=1)
    dist = np.linalg.norm(cloud.points[:, None] - centres[None], axis=2)
    only0 = (seen[:, 0] == 1) & (seen[:, 1] == -1)
    only1 = (seen[:, 1] == 1) & (seen[:, 0] == -1)
    both = (seen == 1).all(axis=1) & (np.abs(dist[:, 0] - dist[:, 1]) > 0.15)
    assert only0.sum() > 20 and only1.sum() > 20 and both.sum() > 20
    assert (cloud.frames[only0] == 0).all() and (cloud.frames[only1] == 1).all()
    assert (cloud.frames[both] == dist[both].argmin(axis=1)).all()
    assert (cloud.colors[only0] == COLOURS[0]).all() and (cloud.colors[only1] == COLOURS[1]).all()
    assert cloud.meta["layout"] == "plain" and cloud.meta["frames"] == 2 and cloud.meta["voxel_m"] == 0.1
    assert cloud.meta["raw_points"] == 2 * 64 * 48 and len(cloud) < cloud.meta["raw_points"]
    json.dumps(cloud.meta)
    again = fuse_sequence(read_sequence(tmp_path), voxel_m=0.1)
    assert np.array_equal(again.points, cloud.points) and np.array_equal(again.frames, cloud.frames)


def test_every_depth_scale_and_intrinsics_options(tmp_path):
    write_plain(tmp_path, scale=0.0005, camera_extra={"depth_scale": 0.0005})
    seq = read_sequence(tmp_path, every=2)
    assert [f.name for f in seq.frames] == ["00000", "00002"] and seq.depth_scale == 0.0005
    assert np.abs(fuse_sequence(seq).points[:, 2] - PLANE_Z).max() < 0.01
    doubled = read_sequence(tmp_path, every=3, depth_scale=0.001)
    assert len(doubled.frames) == 1 and np.allclose(
        fuse_sequence(doubled).points[:, 2], 2 * PLANE_Z, atol=0.01
    )
    wide = read_sequence(tmp_path, intrinsics="120,120,31.5,23.5")
    assert wide.camera == Camera(120.0, 120.0, 31.5, 23.5, 64, 48)
    refused(lambda: read_sequence(tmp_path, every=0), "every = 0")
    refused(lambda: read_sequence(tmp_path, depth_scale=-1.0), "positive")


def test_bad_plain_folders(tmp_path):
    refused(lambda: read_sequence(tmp_path / "nope"), "not found")
    (tmp_path / "empty").mkdir()
    assert sequence_layout(tmp_path / "empty") is None
    refused(lambda: read_sequence(tmp_path / "empty"), "not an RGB-D sequence", "TUM (", "cameras.json")
    root = write_plain(tmp_path / "a")
    (root / "pose" / "00001.txt").unlink()
    (root / "pose" / "00002.txt").unlink()
    refused(lambda: read_sequence(root), "2 of 3 depth frames have no pose", "00001.png", "pose/00001.txt")
    root = write_plain(tmp_path / "b")
    write_png(root / "depth" / "00002.png", np.full((24, 32), 2.0))
    refused(lambda: read_sequence(root), "differ in size", "00002.png is 32x24", "00000.png is 64x48")
    root = write_plain(tmp_path / "c")
    np.savetxt(root / "pose" / "00001.txt", np.diag([2.0, 2.0, 2.0, 1.0]))
    refused(lambda: read_sequence(root), "pose/00001.txt", "not a rigid transform")
    np.savetxt(root / "pose" / "00001.txt", np.eye(3))
    refused(lambda: read_sequence(root), "4x4", "9 numbers")
    root = write_plain(tmp_path / "far", [POSES[0], pose(centre=(800.0, 0.0, 0.0))])  # millimetres?
    refused(lambda: fuse_sequence(read_sequence(root)), "too large for a room", "poses are in metres")
    root = write_plain(tmp_path / "d", camera_extra={"width": 640, "height": 480})
    refused(lambda: read_sequence(root), "640x480", "64x48", "-K")
    (tmp_path / "e" / "depth").mkdir(parents=True)
    (tmp_path / "e" / "pose").mkdir()
    (tmp_path / "e" / "cameras.json").write_text(json.dumps(CAM.to_dict()))
    refused(lambda: read_sequence(tmp_path / "e"), "no depth frames")


def test_unreadable_depth_skipped_at_fusion(tmp_path):
    root = write_plain(tmp_path)
    (root / "depth" / "00001.png").write_bytes(b"not a png at all")
    seq = read_sequence(root)
    cloud = fuse_sequence(seq)
    assert "skipped 1 of 3 frames with unreadable depth" in cloud.warnings
    assert set(np.unique(cloud.frames)) == {0, 2} and cloud.meta["frames"] == 2
    for i in range(3):  # a valid header but truncated data: only decoding finds it
        path = root / "depth" / f"{i:05d}.png"
        write_png(path, plane_depth(POSES[0]))
        path.write_bytes(path.read_bytes()[:60])
    refused(lambda: fuse_sequence(read_sequence(root)), "none of the 3 depth frames could be read")
    for i in range(3):
        (root / "depth" / f"{i:05d}.png").write_bytes(b"junk")
    refused(lambda: read_sequence(root), "none of the 3 depth images")


def quaternion_z(angle):
    return (0.0, 0.0, math.sin(angle / 2), math.cos(angle / 2))


def test_tum_association(tmp_path):
    tum = Camera.preset("tum")
    stamps = ["1.000000", "1.100000", "1.200000"]
    quarter_turn_z = np.array([[0.0, -1.0, 0.0], [1.0, 0.0, 0.0], [0.0, 0.0, 1.0]])
    poses = {"0.995": pose(), "1.105": pose(quarter_turn_z, (0.5, 0.0, 0.0)), "1.500": pose()}
    truth = ["# ground truth", "# timestamp tx ty tz qx qy qz qw"]
    for t, m in poses.items():
        q = quaternion_z(math.pi / 2) if t == "1.105" else (0.0, 0.0, 0.0, 1.0)
        truth.append(" ".join([t, *map(str, m[:3, 3]), *map(str, q)]))
    (tmp_path / "groundtruth.txt").write_text("\n".join(truth) + "\n")
    depth_lines, rgb_lines = ["# depth maps"], ["# color images"]
    for i, stamp in enumerate(stamps):
        m = poses[["0.995", "1.105", "1.500"][i]]
        write_png(tmp_path / "depth" / f"{stamp}.png", plane_depth(m, tum), scale=1 / 5000)
        write_rgb(tmp_path / "rgb" / f"{stamp}.png", COLOURS[i], (480, 640))
        depth_lines.append(f"{stamp} depth/{stamp}.png")
        rgb_lines.append(f"{float(stamp) + 0.01:.6f} rgb/{stamp}.png")
    (tmp_path / "depth.txt").write_text("\n".join(depth_lines) + "\n")
    (tmp_path / "rgb.txt").write_text("\n".join(rgb_lines) + "\n")
    seq = read_sequence(tmp_path)
    assert seq.layout == "tum" and seq.camera == tum and seq.depth_scale == pytest.approx(1 / 5000)
    assert [f.name for f in seq.frames] == stamps[:2]
    assert seq.warnings == ["dropped 1 of 3 depth frames without a pose within 0.02 s"]
    assert seq.frames[1].rgb_path == tmp_path / "rgb" / f"{stamps[1]}.png"
    assert np.allclose(seq.frames[1].world_from_camera, poses["1.105"])
    cloud = fuse_sequence(seq)
    assert np.abs(cloud.points[:, 2] - PLANE_Z).max() < 0.01 and cloud.meta["pixel_step"] == 2
    (tmp_path / "groundtruth.txt").write_text("5.0 0 0 0 0 0 0 1\n")
    refused(lambda: read_sequence(tmp_path), "none of the 3 depth frames has a pose")


def test_scannet_layout_skips_inf_poses(tmp_path):
    names = ["0", "1", "2", "10"]
    for i, name in enumerate(names):
        m = POSES[i % 3]
        write_png(tmp_path / "depth" / f"{name}.png", plane_depth(m))
        write_rgb(tmp_path / "color" / f"{name}.jpg", COLOURS[i % 3], (96, 128))  # colour camera 2x
        (tmp_path / "pose").mkdir(exist_ok=True)
        np.savetxt(tmp_path / "pose" / f"{name}.txt", np.full((4, 4), -np.inf) if name == "1" else m)
    (tmp_path / "intrinsic").mkdir()
    k = np.eye(4)
    k[:3, :3] = CAM.K
    np.savetxt(tmp_path / "intrinsic" / "intrinsic_depth.txt", k)
    seq = read_sequence(tmp_path)
    assert seq.layout == "scannet" and seq.camera == CAM and seq.depth_scale == 0.001
    assert [f.name for f in seq.frames] == ["0", "2", "10"]
    assert seq.warnings == ["skipped 1 of 4 frames with invalid (inf/NaN) poses"]
    cloud = fuse_sequence(seq)
    assert np.abs(cloud.points[:, 2] - PLANE_Z).max() < 0.01 and cloud.frame_names == ["0", "2", "10"]
    near_colour = np.abs(cloud.colors[cloud.frames == 0].astype(int) - COLOURS[0]).max(axis=1) < 40
    assert near_colour.mean() > 0.5  # registered colour image of another size, resized to the depth


def write_redwood(root, poses, cam):
    for i, m in enumerate(poses):
        write_png(root / "depth" / f"{i:05d}.png", plane_depth(m, cam))
        write_rgb(root / "color" / f"{i:05d}.jpg", COLOURS[i], (cam.height, cam.width))
    blocks = [
        f"{i} {i} {i + 1}\n" + "\n".join(" ".join(map(str, row)) for row in m) for i, m in enumerate(poses)
    ]
    (root / "trajectory.log").write_text("\n".join(blocks) + "\n")
    matrix = cam.K.T.ravel().tolist()  # Open3D stores it column-major
    (root / "camera.json").write_text(
        json.dumps({"width": cam.width, "height": cam.height, "intrinsic_matrix": matrix})
    )


def test_redwood_layout(tmp_path):
    cam = Camera(60.0, 62.0, 30.0, 25.0, 64, 48)
    write_redwood(tmp_path, POSES, cam)
    seq = read_sequence(tmp_path)
    assert seq.layout == "redwood" and seq.camera == cam and len(seq.frames) == 3
    assert np.allclose(seq.frames[2].world_from_camera, POSES[2])
    assert np.abs(fuse_sequence(seq).points[:, 2] - PLANE_Z).max() < 0.01
    write_png(tmp_path / "depth" / "00003.png", plane_depth(POSES[0], cam))
    refused(lambda: read_sequence(tmp_path), "1 of 4 depth frames have no pose", "00003.png")


# Camera centres of the five poses in the shared data's redwood/trajectory.log.
REDWOOD_CENTRES = [
    (-0.31057997, 0.57301224, 2.12648002),
    (-0.31035872, 0.59630940, 2.12603614),
    (-0.30973732, 0.62044956, 2.12478944),
    (-0.30877928, 0.64529891, 2.12286737),
    (-0.30754812, 0.67072365, 2.12039735),
]


def test_real_redwood_sequence():
    root = SHARED_DATA / "redwood"
    if not root.is_dir():
        pytest.skip(f"{root} is absent (shared data is not part of the repository)")
    seq = read_sequence(root)
    assert seq.layout == "redwood" and len(seq.frames) == 5 and seq.warnings == []
    assert seq.camera == Camera(525.0, 525.0, 319.5, 239.5, 640, 480) and seq.depth_scale == 0.001
    cloud = fuse_sequence(seq)
    assert 10_000 < len(cloud) < cloud.meta["raw_points"] and cloud.colors is not None
    extent = cloud.points.max(axis=0) - cloud.points.min(axis=0)
    assert 1.0 < np.linalg.norm(extent) < 10.0 and (extent < 6.0).all()
    used = np.unique(cloud.viewpoints, axis=0)
    assert np.allclose(used, np.array(REDWOOD_CENTRES), atol=1e-6)
    assert cloud.frame_names == ["00000", "00001", "00002", "00003", "00004"]


def test_mismatched_counts_are_said(tmp_path):
    """A frame without its colour image and a pose without its depth frame are fitted around, and said."""
    root = write_plain(tmp_path)
    (root / "color" / "00001.png").unlink()
    np.savetxt(root / "pose" / "00007.txt", POSES[0])
    seq = read_sequence(root)
    assert [f.name for f in seq.frames] == ["00000", "00001", "00002"]
    assert [f.rgb_path is None for f in seq.frames] == [False, True, False]
    assert len(seq.warnings) == 2, seq.warnings
    extra, colourless = seq.warnings
    assert extra.startswith("1 pose files have no depth frame (first: pose/00007.txt)")
    assert colourless.startswith("1 of 3 depth frames have no colour image (first: 00001.png")
    for p in (root / "color").iterdir():  # no colour at all is a layout of its own: nothing to say
        p.unlink()
    (root / "pose" / "00007.txt").unlink()
    assert read_sequence(root).warnings == []

"""Fusing a sequence, checked point by point: each fused point is the mean of the pixels in its voxel, the
voxels come out in one order whatever the signs of their coordinates, each keeps the frame whose camera is
nearest its centre, colour mixes coloured and colourless frames, and every limit holds at its boundary."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.io.sequence import read_sequence
from cuboidcli.load.fuse import _HALF, _frame_rows, fuse_sequence
from tests.io.test_sequence import CAM, COLOURS, POSES, pose, refused, write_plain, write_png, write_rgb


def flat_sequence(root, depth_m: float, poses, colours=None):
    """A plain-layout sequence whose every frame sees a fronto-parallel wall at exactly ``depth_m``;
    frame i has colour ``colours[i]`` or none (None)."""
    colours = colours or COLOURS[: len(poses)]
    write_plain(root, poses)
    for i, colour in enumerate(colours):
        write_png(root / "depth" / f"{i:05d}.png", np.full((CAM.height, CAM.width), depth_m))
        rgb = root / "color" / f"{i:05d}.png"
        if colour is None:
            rgb.unlink()
        else:
            write_rgb(rgb, colour)
    return read_sequence(root)


def world_points(seq, k):
    """Frame k's back-projected pixels in the world frame, computed here from the camera model."""
    frame = seq.frames[k]
    u, v = np.meshgrid(np.arange(CAM.width, dtype=float), np.arange(CAM.height, dtype=float))
    depth = np.full(u.shape, 2.0)
    local = np.stack([(u - CAM.cx) / CAM.fx * depth, (v - CAM.cy) / CAM.fy * depth, depth], -1).reshape(-1, 3)
    m = frame.world_from_camera
    return local @ m[:3, :3].T + m[:3, 3]


def test_each_point_is_the_mean_of_its_voxel_in_lexicographic_voxel_order(tmp_path):
    # the camera sits at the origin, so the wall's voxels have negative and positive x and y indices
    seq = flat_sequence(tmp_path, 2.0, [pose()])
    voxel = 0.05
    cloud = fuse_sequence(seq, voxel_m=voxel)
    pts = world_points(seq, 0)
    idx = np.floor(pts / voxel).astype(np.int64)
    voxels, inverse = np.unique(idx, axis=0, return_inverse=True)  # sorted by x, then y, then z
    means = np.zeros((len(voxels), 3))
    np.add.at(means, inverse.ravel(), pts)
    means /= np.bincount(inverse.ravel())[:, None]
    assert (voxels[:, 0] < 0).any() and (voxels[:, 0] >= 0).any() and (voxels[:, 1] < 0).any()
    assert cloud.points.shape == means.shape
    assert np.allclose(cloud.points, means, atol=1e-12)


def test_the_distance_kept_is_from_the_voxel_centre_to_the_camera(tmp_path):
    seq = flat_sequence(tmp_path, 2.0, [pose(centre=(0.3, -0.2, 0.1))])
    voxel = 0.1
    key, pts, ones, cols, has, dist, frames = _frame_rows(seq, 0, 1, voxel, 6.0)
    centres = (np.floor(pts / voxel) + 0.5) * voxel
    assert np.allclose(dist, np.linalg.norm(centres - [0.3, -0.2, 0.1], axis=1), atol=1e-12)
    assert len(np.unique(key)) == len(np.unique(np.floor(pts / voxel), axis=0))
    assert (ones == 1).all() and (has == 1).all() and (cols == COLOURS[0]).all() and (frames == 0).all()


def test_a_voxel_keeps_the_frame_of_its_nearest_camera_centre(tmp_path):
    # two cameras one above the other looking along z: a voxel's centre decides which is nearer, and the
    # half-voxel offset of that centre matters for voxels near the bisecting plane y = 0.05
    poses = [pose(centre=(0.0, 0.0, 0.0)), pose(centre=(0.0, 0.1, 0.0))]
    seq = flat_sequence(tmp_path, 2.0, poses)
    voxel = 0.08  # the voxel [0.0, 0.08) has its centre below y = 0.05 and three quarters of it above
    cloud = fuse_sequence(seq, voxel_m=voxel)
    centres = (np.floor(cloud.points / voxel) + 0.5) * voxel
    nearer = np.linalg.norm(centres - poses[1][:3, 3], axis=1) < np.linalg.norm(
        centres - poses[0][:3, 3], axis=1
    )
    seen_by_both = np.abs(cloud.points[:, 1]) < 0.5
    assert (cloud.frames[seen_by_both] == nearer[seen_by_both]).all()
    assert 0 < nearer[seen_by_both].sum() < seen_by_both.sum()


def test_coloured_and_colourless_frames_mix(tmp_path):
    seq = flat_sequence(tmp_path, 2.0, POSES[:2], colours=[COLOURS[0], None])
    cloud = fuse_sequence(seq, voxel_m=0.1)
    frames_that_saw = [set() for _ in range(len(cloud))]
    for k in range(2):
        pts = world_points(seq, k)
        voxels = {tuple(v) for v in np.floor(pts / 0.1).astype(int)}
        for i, v in enumerate(np.floor(cloud.points / 0.1).astype(int)):
            if tuple(v) in voxels:
                frames_that_saw[i].add(k)
    only_colourless = np.array([s == {1} for s in frames_that_saw])
    coloured = np.array([0 in s for s in frames_that_saw])
    assert only_colourless.sum() > 10 and coloured.sum() > 10
    assert (cloud.colors[only_colourless] == 128).all()  # grey: no colour was seen there
    assert (cloud.colors[coloured] == COLOURS[0]).all()  # the colourless frame does not darken it
    no_colour = flat_sequence(tmp_path / "none", 2.0, POSES[:2], colours=[None, None])
    assert fuse_sequence(no_colour, voxel_m=0.1).colors is None


def test_depth_exactly_at_the_limit_is_kept(tmp_path):
    seq = flat_sequence(tmp_path, 2.0, [pose()])
    assert len(fuse_sequence(seq, max_depth_m=2.0).points) == len(fuse_sequence(seq).points)
    refused(lambda: fuse_sequence(seq, max_depth_m=1.999), "no valid depth within 1.999 m in any frame")


def test_the_defaults_are_2_cm_voxels_and_6_m_depth(tmp_path):
    cloud = fuse_sequence(flat_sequence(tmp_path / "near", 5.9, [pose()]))
    assert cloud.meta["voxel_m"] == 0.02 and cloud.meta["max_depth_m"] == 6.0
    refused(
        lambda: fuse_sequence(flat_sequence(tmp_path / "far", 6.1, [pose()])), "no valid depth within 6.0 m"
    )


@pytest.mark.parametrize(("voxel_m", "max_depth_m"), [(0.0, 6.0), (-0.1, 6.0), (0.02, 0.0), (0.02, -1.0)])
def test_sizes_that_are_not_positive_are_refused(tmp_path, voxel_m, max_depth_m):
    seq = flat_sequence(tmp_path, 2.0, [pose()])
    refused(lambda: fuse_sequence(seq, voxel_m=voxel_m, max_depth_m=max_depth_m), "must be positive metres")


def test_a_voxel_larger_than_a_metre_is_accepted(tmp_path):
    cloud = fuse_sequence(flat_sequence(tmp_path, 2.0, [pose()]), voxel_m=1.5, unit_check=False)
    assert 1 <= len(cloud.points) <= 4 and cloud.meta["voxel_m"] == 1.5


def test_one_voxel_is_a_result(tmp_path):
    # the whole view of a 2 m wall falls into one 8 m voxel when the camera sits inside it
    seq = flat_sequence(tmp_path, 2.0, [pose(centre=(4.0, 4.0, 0.5))])
    cloud = fuse_sequence(seq, voxel_m=8.0, unit_check=False)
    assert len(cloud.points) == 1 and cloud.frames.tolist() == [0]


def test_voxel_indices_beyond_the_key_range_are_refused(tmp_path):
    # with 4 m voxels a camera 2^22 m + 2 m from the origin puts every pixel into voxel column 2^20
    # exactly: one past the last index a 21-bit key holds
    voxel = 4.0
    seq = flat_sequence(tmp_path, 2.0, [pose(centre=(voxel * _HALF + 2.0, 0.0, 0.0))])
    assert (np.floor(world_points(seq, 0)[:, 0] / voxel) == _HALF).all()
    refused(lambda: fuse_sequence(seq, voxel_m=voxel, unit_check=False), "are the poses in metres?")
    # tiny voxels put every depth out of the key range while some x and y stay in it: still refused
    near_far = flat_sequence(tmp_path / "nf", 2.0, [pose()])
    refused(lambda: fuse_sequence(near_far, voxel_m=1e-6, unit_check=False), "are the poses in metres?")


def test_a_voxel_of_one_coloured_pixel_keeps_its_colour(tmp_path):
    seq = flat_sequence(tmp_path, 2.0, [pose()])
    cloud = fuse_sequence(seq, voxel_m=0.005)  # a pixel is 3.3 cm wide at 2 m: one pixel per voxel
    assert len(cloud.points) == CAM.width * CAM.height and (cloud.colors == COLOURS[0]).all()


def test_a_depth_limit_under_a_metre(tmp_path):
    near = flat_sequence(tmp_path, 0.4, [pose()])
    assert len(fuse_sequence(near, max_depth_m=0.5, unit_check=False).points) > 100

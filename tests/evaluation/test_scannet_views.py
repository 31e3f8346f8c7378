"""Scans rendered as TUM sequences (cuboidcli.evaluation.scannet_views): a box room with a cabinet and a
crate hidden behind it, sampled as points, rendered, written and read back through the project's own
sequence reader and fusion; the fused points must lie on the room's surfaces, and what the views see must
leave out what the cabinet hides."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.scannet import ScanTruth, read_truth
from cuboidcli.evaluation.scannet_views import (
    look_at,
    loop_poses,
    render_points,
    render_scan,
    scan_colors,
    seen_boxes,
    seen_truth,
    tum_camera,
    write_tum,
)
from cuboidcli.io.sequence import read_sequence
from cuboidcli.load.fuse import fuse_sequence
from tests.conftest import SHARED_DATA

ROOM = np.array([4.0, 3.0, 2.5])  # the room spans [0, ROOM], floor at z = 0
#: (min corner, max corner) of the cabinet and of a low crate right behind it, seen from x = 0.5.
CABINET = (np.array([2.0, 1.2, 0.0]), np.array([2.6, 1.8, 1.2]))
CRATE = (np.array([2.8, 1.3, 0.0]), np.array([3.1, 1.7, 0.5]))
UP = np.array([0.0, 0.0, 1.0])


def _box_faces(lo, hi, rng, per_m2: float, inward: bool = False) -> np.ndarray:
    """Points sampled uniformly on the faces of the box [lo, hi] (no top face for a room: it has no
    ceiling, as a scan's often has none)."""
    out = []
    for axis in range(3):
        for side, value in ((0, lo[axis]), (1, hi[axis])):
            if inward and axis == 2 and side == 1:
                continue
            other = [a for a in range(3) if a != axis]
            area = np.prod(hi[other] - lo[other])
            n = max(1, int(area * per_m2))
            p = np.empty((n, 3))
            p[:, axis] = value
            for a in other:
                p[:, a] = rng.uniform(lo[a], hi[a], n)
            out.append(p)
    return np.concatenate(out)


@pytest.fixture(scope="module")
def room():
    """(points, colours, instance ids): room shell 0, cabinet 1, crate 2."""
    rng = np.random.default_rng(0)
    parts = [
        _box_faces(np.zeros(3), ROOM, rng, 2500, inward=True),
        _box_faces(*CABINET, rng, 2500),
        _box_faces(*CRATE, rng, 2500),
    ]
    points = np.concatenate(parts)
    instance = np.concatenate([np.full(len(p), i) for i, p in enumerate(parts)])
    colors = np.array([[200, 200, 190], [150, 80, 40], [40, 120, 200]], dtype=np.uint8)[instance]
    return points, colors, instance


def _surface_distance(p: np.ndarray) -> np.ndarray:
    """(N,) distance of points inside the room to the nearest surface: the shell or a box."""
    d = np.minimum(p, ROOM - p)[:, :2].min(1)
    d = np.minimum(np.abs(d), np.abs(p[:, 2]))  # the floor (there is no ceiling)
    for lo, hi in (CABINET, CRATE):
        q = np.abs(p - (lo + hi) / 2) - (hi - lo) / 2
        signed = np.linalg.norm(np.maximum(q, 0), axis=1) + np.minimum(q.max(1), 0)
        d = np.minimum(d, np.abs(signed))
    return d


def test_rendered_views_read_back_onto_the_source_surfaces(room, tmp_path):
    points, colors, _ = room
    camera = tum_camera(320, 240)
    poses = loop_poses(points, UP, 0.0, views=6)
    centres = np.array([p[:3, 3] for p in poses])
    # inside the room, away from its walls, at head height
    assert (centres[:, :2] > 0.5).all() and (centres[:, :2] < ROOM[:2] - 0.5).all()
    assert np.allclose(centres[:, 2], 1.45)
    depths, rgbs, seen = render_points(points, colors, poses, camera)
    assert all((d > 0).mean() > 0.6 for d in depths)  # a closed room: the views are mostly drawn
    seq = read_sequence(write_tum(tmp_path / "seq", depths, rgbs, poses))
    assert seq.layout == "tum" and len(seq.frames) == 6
    assert (seq.camera.fx, seq.camera.cx, seq.camera.width) == (camera.fx, camera.cx, 320)
    for frame, pose in zip(seq.frames, poses, strict=True):
        assert np.allclose(frame.world_from_camera, pose, atol=1e-6)
    cloud = fuse_sequence(seq, voxel_m=0.01)
    d = _surface_distance(cloud.points)
    # the fused points lie on the sampled surfaces: depth is quantised to 0.2 mm, a splat's depth is its
    # point's across the disc, so a surface seen at a slant is off by a little
    assert np.median(d) < 0.005 and np.percentile(d, 95) < 0.02
    # colours survive: points on the cabinet's front face carry the cabinet's colour
    front = (np.abs(cloud.points[:, 0] - CABINET[0][0]) < 0.01) & (np.abs(cloud.points[:, 1] - 1.5) < 0.2)
    front &= np.abs(cloud.points[:, 2] - 0.6) < 0.4
    assert front.sum() > 20
    assert np.abs(cloud.colors[front].astype(int) - [150, 80, 40]).max(1).mean() < 20


def test_points_hidden_behind_the_cabinet_are_not_seen(room):
    points, colors, instance = room
    camera = tum_camera(320, 240)
    # one view from x = 0.5 straight at the cabinet, which hides the crate and the wall right behind it
    pose = look_at(np.array([0.5, 1.5, 0.8]), np.array([1.0, 0.0, 0.0]), UP)
    _, _, seen = render_points(points, colors, [pose], camera)
    crate, cabinet = instance == 2, instance == 1
    assert not seen[crate].any()
    # the cabinet's front face, but for its foot below the image's lower edge (z 0.12 at 1.5 m)
    cabinet_front = cabinet & (points[:, 0] == CABINET[0][0]) & (points[:, 2] > 0.15)
    assert seen[cabinet_front].mean() > 0.98
    assert not seen[cabinet & (points[:, 0] == CABINET[1][0])].any()  # its back face
    far_wall = (instance == 0) & (points[:, 0] == ROOM[0])
    behind = far_wall & (np.abs(points[:, 1] - 1.5) < 0.15) & (points[:, 2] < 0.8)
    beside = far_wall & (np.abs(points[:, 1] - 0.5) < 0.1) & (np.abs(points[:, 2] - 1.0) < 0.3)
    assert behind.any() and not seen[behind].any()
    assert seen[beside].mean() > 0.95
    assert not seen[points[:, 0] < 0.5].any()  # the wall behind the camera

    boxes = [Cuboid((lo + hi) / 2, (hi - lo) / 2, np.eye(3), kind="object") for lo, hi in (CABINET, CRATE)]
    truth = ScanTruth("room", points, boxes, np.array([3, 39]), instance, np.array([1, 3, 39])[instance])
    # one view sees the cabinet's front, a fifth of its surface: seen at a share of 0.15, not at one half
    assert seen_boxes(truth, seen).tolist() == [False, False]
    assert seen_boxes(truth, seen, share=0.15).tolist() == [True, False]
    part = seen_truth(truth, seen, share=0.15)
    assert len(part.boxes) == 1 and part.classes.tolist() == [3]
    assert len(part.points) == seen.sum() == len(part.instance) == len(part.semantic)


SCANNET = SHARED_DATA / "scannet"


@pytest.mark.skipif(not (SCANNET / "scene0001_00_vert.npy").is_file(), reason="no shared ScanNet scans")
def test_a_real_scan_rendered_in_four_views_fuses_back_onto_its_points(tmp_path):
    truth = read_truth(SCANNET, "scene0001_00")
    rendered = render_scan(truth, scan_colors(SCANNET, "scene0001_00"), tmp_path / "seq", views=4)
    assert 0.1 < rendered.seen.mean() < 1.0
    assert len(rendered.truth.boxes) <= len(truth.boxes)
    cloud = fuse_sequence(read_sequence(rendered.folder))
    sample = cloud.points[np.random.default_rng(0).choice(len(cloud.points), 1500, replace=False)]
    nearest = np.array([np.linalg.norm(truth.points - p, axis=1).min() for p in sample])
    # the scan's points lie 1.6 cm apart (median; 3.7 cm to the sixth nearest), so a fused point on the
    # surface between them is a centimetre or two from the nearest; a disc's rim reaches past an edge
    assert np.median(nearest) < 0.03 and np.mean(nearest < 0.05) > 0.85

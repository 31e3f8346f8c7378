"""Room-level metrics (cuboidcli.evaluation.scene) on hand-made rooms with known numbers."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.iou import box_iou
from cuboidcli.evaluation.scene import (
    aggregate_scenes,
    planar_iou,
    point_box_distance,
    scene_metrics,
    slab_plane,
    surface_distances,
)


def rot_z(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def rot_x(angle: float) -> np.ndarray:
    c, s = math.cos(angle), math.sin(angle)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def face_grid(box: Cuboid, faces, spacing: float = 0.05) -> np.ndarray:
    """Points on a regular grid over the given faces of a box; faces as (axis, sign), e.g. (2, 1) = top."""
    out = []
    for axis, sign in faces:
        a, b = [k for k in range(3) if k != axis]
        na, nb = (int(round(2 * box.half_size[k] / spacing)) for k in (a, b))
        ua = (np.arange(na) + 0.5) / na * 2 - 1
        ub = (np.arange(nb) + 0.5) / nb * 2 - 1
        ga, gb = np.meshgrid(ua, ub, indexing="ij")
        local = np.zeros((ga.size, 3))
        local[:, axis] = sign * box.half_size[axis]
        local[:, a], local[:, b] = ga.ravel() * box.half_size[a], gb.ravel() * box.half_size[b]
        out.append(local @ box.rotation.T + box.center)
    return np.concatenate(out)


SIDES_AND_TOP = [(0, -1), (0, 1), (1, -1), (1, 1), (2, 1)]


@pytest.fixture(scope="module")
def room():
    """A 4 x 3 m floor, two walls, a cabinet and a turned box: (gt cuboids, points (M, 3), ids (M,))."""
    gt = [
        Cuboid([2.0, 1.5, -0.025], [2.0, 1.5, 0.025], np.eye(3), kind="floor"),
        Cuboid([2.0, -0.025, 1.25], [2.0, 0.025, 1.25], np.eye(3), kind="wall"),
        Cuboid([-0.025, 1.5, 1.25], [0.025, 1.5, 1.25], np.eye(3), kind="wall"),
        Cuboid([0.8, 0.5, 0.45], [0.4, 0.25, 0.45], np.eye(3)),
        Cuboid([2.6, 1.8, 0.3], [0.5, 0.35, 0.3], rot_z(0.5)),
    ]
    faces = [[(2, 1)], [(1, 1)], [(0, 1)], SIDES_AND_TOP, SIDES_AND_TOP]
    points, ids = [], []
    for k, (box, f) in enumerate(zip(gt, faces, strict=True)):
        p = face_grid(box, f)
        points.append(p)
        ids.append(np.full(len(p), k + 1))
    return gt, np.concatenate(points), np.concatenate(ids)


def test_point_box_distance_by_hand():
    box = Cuboid([0.0, 0.0, 0.0], [1.0, 0.5, 0.25], np.eye(3))
    points = np.array(
        [
            [0.0, 0.0, 0.0],  # centre: 0.25 to the top and bottom faces
            [0.9, 0.0, 0.0],  # inside, 0.1 from the +x face
            [1.0, 0.2, 0.0],  # on the +x face
            [2.0, 1.5, 1.25],  # outside beyond a corner: (1, 1, 1) away
            [0.0, 0.0, 0.75],  # above the top face
        ]
    )
    assert point_box_distance(points, [box]) == pytest.approx([0.25, 0.1, 0.0, math.sqrt(3.0), 0.5])
    assert np.isinf(point_box_distance(points, [])).all()


def test_point_box_distance_turns_with_the_box():
    # the same box turned by 30 degrees about z; points placed along its own axes
    c, s = math.cos(math.pi / 6), math.sin(math.pi / 6)
    along, across = np.array([c, s, 0.0]), np.array([-s, c, 0.0])
    box = Cuboid([1.0, 2.0, 0.0], [1.0, 0.5, 0.25], rot_z(math.pi / 6))
    centre = box.center
    points = np.array(
        [
            centre + 1.5 * along,  # 0.5 past the far end
            centre + 0.8 * across,  # 0.3 beside the long face
            centre + [0.0, 0.0, 0.1],  # inside, 0.15 under the top
            centre + 2.0 * along + 1.0 * across,  # beyond a corner by (1, 0.5)
        ]
    )
    expected = [0.5, 0.3, 0.15, math.hypot(1.0, 0.5)]
    assert point_box_distance(points, [box]) == pytest.approx(expected)


def test_the_nearest_surface_wins():
    a = Cuboid([0.0, 0.0, 0.0], [0.5, 0.5, 0.5], np.eye(3))
    b = Cuboid([3.0, 0.0, 0.0], [0.5, 0.5, 0.5], np.eye(3))
    dist, index = surface_distances(np.array([[1.0, 0.0, 0.0], [2.2, 0.0, 0.0], [0.0, 0.0, 0.0]]), [a, b])
    assert dist == pytest.approx([0.5, 0.3, 0.5]) and index.tolist() == [0, 1, 0]


def test_the_ground_truth_scores_full_marks(room):
    gt, points, ids = room
    m = scene_metrics(gt, gt, points, ids)
    assert m["n_cuboids"] == 5 and m["points"] == len(points)
    assert m["auc20cm_pct"] == pytest.approx(100.0, abs=1e-6) and m["auc5cm_pct"] == pytest.approx(100.0)
    assert m["mean_distance_cm"] == pytest.approx(0.0, abs=1e-9)
    assert m["object_recall_pct"] == 100.0 and m["object_precision_pct"] == 100.0
    assert m["objects_eligible"] == 5
    for t in ("0.25", "0.5"):
        assert m[f"object_box_recall_iou{t}_pct"] == 100.0 and m[f"shell_box_recall_iou{t}_pct"] == 100.0
        assert m[f"object_box_precision_iou{t}_pct"] == 100.0
    assert (m["gt_objects"], m["pred_objects"], m["gt_shell"], m["pred_shell"]) == (2, 2, 3, 3)


def test_an_empty_prediction_scores_nothing(room):
    gt, points, ids = room
    m = scene_metrics([], gt, points, ids)
    assert m["auc20cm_pct"] == 0.0 and m["auc5cm_pct"] == 0.0 and math.isinf(m["mean_distance_cm"])
    assert m["object_recall_pct"] == 0.0 and math.isnan(m["object_precision_pct"])
    assert m["object_box_recall_iou0.25_pct"] == 0.0 and m["shell_box_recall_iou0.5_pct"] == 0.0
    assert math.isnan(m["object_box_precision_iou0.25_pct"])


def test_a_box_shifted_by_half_its_size(room):
    gt, points, ids = room
    turned = gt[4]
    # along its own x axis by its half-size: the overlap is half the box, IoU = 0.5 / 1.5 = 1/3
    shifted = Cuboid(
        turned.center + turned.rotation[:, 0] * turned.half_size[0], turned.half_size, turned.rotation
    )
    m = scene_metrics(gt[:4] + [shifted], gt, points, ids)
    assert m["object_box_recall_iou0.25_pct"] == 100.0
    assert m["object_box_recall_iou0.5_pct"] == 50.0 and m["object_box_precision_iou0.5_pct"] == 50.0
    assert m["shell_box_recall_iou0.5_pct"] == 100.0
    # the shifted box no longer holds the box's points: a third of them (7.8 % of all) end up 0.3-0.5 m away
    assert m["auc20cm_pct"] < 97.5 and m["mean_distance_cm"] > 0.5


def test_object_recall_follows_the_mutual_majority_rule(room):
    gt, points, ids = room
    # without the turned box its points stay unassigned (> 5 cm from any surface) except the ones near
    # the floor: four of five objects explained, every cuboid explains one
    m = scene_metrics(gt[:4], gt, points, ids)
    assert m["objects_explained"] == 4 and m["object_recall_pct"] == 80.0
    assert m["object_precision_pct"] == 100.0
    # one box around both objects: it takes 877 of the cabinet's 1096 points and 685 of the turned box's
    # (the rest are nearer the floor), so 56 % of its points lie on the cabinet: it explains the cabinet
    # but not the turned box, though it holds most of that box's points too
    both = Cuboid([1.8, 1.3, 0.475], [1.5, 1.1, 0.475], np.eye(3))
    m = scene_metrics(gt[:3] + [both], gt, points, ids, inlier_m=2.0)
    assert m["objects_explained"] == 4 and m["cuboids_explaining"] == 4
    # a duplicate of the cabinet box gets no point (ties go to the first box): it explains nothing
    m = scene_metrics(gt + [gt[3]], gt, points, ids)
    assert m["object_recall_pct"] == 100.0 and m["object_precision_pct"] == pytest.approx(100.0 * 5 / 6)


def test_boxes_match_within_their_kind(room):
    gt, points, ids = room
    # the floor predicted as an "object": right place, wrong kind
    relabelled = [Cuboid(gt[0].center, gt[0].half_size, gt[0].rotation), *gt[1:]]
    m = scene_metrics(relabelled, gt, points, ids)
    assert m["shell_box_recall_iou0.5_pct"] == pytest.approx(200.0 / 3.0)
    assert m["object_box_precision_iou0.25_pct"] == pytest.approx(200.0 / 3.0)


def test_aggregate_pools_ratios_and_averages_the_rest(room):
    gt, points, ids = room
    full = scene_metrics(gt, gt, points, ids)
    half = scene_metrics(gt[:3] + [gt[3]], gt, points, ids)  # 4 of 5 objects, 1 of 2 object boxes
    empty = scene_metrics([], gt[:3], points[ids <= 3], ids[ids <= 3])  # 3 shell objects, no boxes
    agg = aggregate_scenes([full, half, empty])
    assert agg["scenes"] == 3
    # pooled: (5 + 4 + 0) / (5 + 5 + 3), not the mean of 100, 80 and 0
    assert agg["object_recall_pct"] == pytest.approx(100.0 * 9 / 13)
    assert agg["objects_eligible"] == 13 and agg["n_cuboids"] == pytest.approx(3.0)
    assert agg["object_box_recall_iou0.5_pct"] == pytest.approx(100.0 * 3 / 4)
    assert agg["object_box_precision_iou0.5_pct"] == pytest.approx(100.0)
    assert agg["auc20cm_pct"] == pytest.approx((full["auc20cm_pct"] + half["auc20cm_pct"] + 0.0) / 3)
    assert math.isinf(agg["mean_distance_cm"])
    assert aggregate_scenes([]) == {"scenes": 0}


# The shell is matched in its plane. The ground-truth wall of the room fixture: 4 m x 2.5 m, 5 cm thick,
# its inner face on y = 0; a fitted wall is a 5 mm slab on that face (y in [0, 5 mm]).
GT_WALL = Cuboid([2.0, -0.025, 1.25], [2.0, 0.025, 1.25], np.eye(3), kind="wall")


def fitted_wall(shift_x: float = 0.0, tilt_deg: float = 0.0, offset_y: float = 0.0) -> Cuboid:
    """A 5 mm wall slab on GT_WALL's face, moved along the wall, tilted about the wall's horizontal axis
    (its normal leans away from y) and moved off the face."""
    return Cuboid(
        [2.0 + shift_x, 0.0025 + offset_y, 1.25],
        [2.0, 0.0025, 1.25],
        rot_x(math.radians(tilt_deg)),
        kind="wall",
    )


def test_slab_plane_is_the_thin_axis():
    normal, axes, half = slab_plane(Cuboid([0.0, 0.0, 0.0], [2.0, 0.5, 0.01], rot_z(0.3)))
    assert normal == pytest.approx([0.0, 0.0, 1.0])
    assert axes.T == pytest.approx(rot_z(0.3)[:, :2].T) and half == pytest.approx([2.0, 0.5])


def test_a_thin_slab_on_the_surface_of_a_thick_one():
    # in 3D the slabs only touch: IoU 0 although the wall was found exactly
    assert box_iou(fitted_wall(), GT_WALL) == pytest.approx(0.0, abs=1e-9)
    assert planar_iou(fitted_wall(), GT_WALL) == pytest.approx(1.0)
    # half its length (2 m) along the wall: overlap 2 of 4 m, IoU 2 / (4 + 4 - 2)
    assert planar_iou(fitted_wall(shift_x=2.0), GT_WALL) == pytest.approx(1.0 / 3.0)
    assert planar_iou(fitted_wall(shift_x=-3.0), GT_WALL) == pytest.approx(1.0 / 7.0)
    assert planar_iou(fitted_wall(shift_x=4.5), GT_WALL) == 0.0


def test_slabs_must_share_a_plane():
    assert planar_iou(fitted_wall(tilt_deg=30.0), GT_WALL) == 0.0
    assert planar_iou(fitted_wall(tilt_deg=-12.0), GT_WALL) == 0.0
    # within 10 degrees the tilted rectangle is seen in the wall's plane: its height shrinks by cos(8 deg)
    assert planar_iou(fitted_wall(tilt_deg=8.0), GT_WALL) == pytest.approx(math.cos(math.radians(8.0)))
    # the fitted slab's centre is 2.75 cm from the gt's mid-plane; another 7 cm is still the same wall
    assert planar_iou(fitted_wall(offset_y=0.07), GT_WALL) == pytest.approx(1.0)
    assert planar_iou(fitted_wall(offset_y=0.08), GT_WALL) == 0.0  # 10.75 cm: a wall in front of it
    assert planar_iou(fitted_wall(offset_y=-0.14), GT_WALL) == 0.0  # 11.25 cm behind it
    # a normal pointing the other way is the same plane
    flipped = fitted_wall()
    flipped.rotation = rot_z(math.pi)
    assert planar_iou(flipped, GT_WALL) == pytest.approx(1.0)


def test_planar_iou_of_a_turned_rectangle():
    floor = Cuboid([0.0, 0.0, -0.025], [1.0, 1.0, 0.025], np.eye(3), kind="floor")
    # the same square turned 45 degrees in the plane: the octagon 8 (sqrt 2 - 1) over the union: 1 / sqrt 2
    turned = Cuboid([0.0, 0.0, 0.002], [1.0, 1.0, 0.002], rot_z(math.pi / 4), kind="floor")
    assert planar_iou(turned, floor) == pytest.approx(1.0 / math.sqrt(2.0))
    # the box's axes in another order (its thin axis is its x): the same slab
    stood = Cuboid([0.5, 0.0, 0.002], [0.002, 1.0, 0.5], np.array([[0, 0, 1], [0, 1, 0], [-1, 0, 0]]))
    assert planar_iou(stood, floor) == pytest.approx(0.5)


def test_shell_recall_is_planar(room):
    gt, points, ids = room
    # the three shell slabs fitted as 5 mm slabs on their inner faces; the wall on y = 0 half off its end
    fitted = [
        Cuboid([2.0, 1.5, 0.0025], [2.0, 1.5, 0.0025], np.eye(3), kind="floor"),
        fitted_wall(shift_x=2.0),
        Cuboid([0.0025, 1.5, 1.25], [0.0025, 1.5, 1.25], np.eye(3), kind="wall"),
    ]
    m = scene_metrics(fitted + gt[3:], gt, points, ids)
    assert m["shell_box_recall_iou0.25_pct"] == 100.0 and m["shell_matches_iou0.25"] == 3
    assert m["shell_box_recall_iou0.5_pct"] == pytest.approx(200.0 / 3.0)
    assert m["shell_box_precision_iou0.5_pct"] == pytest.approx(200.0 / 3.0)
    assert m["object_box_recall_iou0.5_pct"] == 100.0  # objects keep the 3D IoU
    # an object box is still matched in 3D: the cabinet as a 5 mm slab on its top finds nothing
    top = Cuboid(gt[3].center + [0.0, 0.0, 0.4475], [0.4, 0.25, 0.0025], np.eye(3))
    m = scene_metrics(gt[:3] + [top, gt[4]], gt, points, ids)
    assert m["object_box_recall_iou0.25_pct"] == 50.0
    # the floor tilted by 30 degrees is no floor
    tilted = Cuboid([2.0, 1.5, 0.0025], [2.0, 1.5, 0.0025], rot_x(math.radians(30.0)), kind="floor")
    m = scene_metrics([tilted, *gt[1:]], gt, points, ids)
    assert m["shell_box_recall_iou0.25_pct"] == pytest.approx(200.0 / 3.0)


def test_object_boxes_are_scored_beside_the_parts(room):
    """objects=: the whole-object boxes make object_box_*, the object cuboids part_box_*."""
    gt, points, instance = room
    objects = [c for c in gt if c.kind == "object"]
    # the top tenth of each object: a table top
    parts = [Cuboid(c.center + [0, 0, 0.9 * c.half_size[2]], c.half_size * [1, 1, 0.1], c.rotation)
             for c in objects]  # fmt: skip
    shell = [c for c in gt if c.kind != "object"]
    row = scene_metrics(shell + parts, gt, points, instance, objects=objects)
    assert row["object_box_recall_iou0.25_pct"] == 100.0 and row["pred_objects"] == len(objects)
    assert row["part_box_recall_iou0.25_pct"] == 0.0 and row["pred_parts"] == len(parts)
    plain = scene_metrics(shell + parts, gt, points, instance)
    assert plain["object_box_recall_iou0.25_pct"] == 0.0 == plain["part_box_recall_iou0.25_pct"]
    pooled = aggregate_scenes([row])
    assert pooled["object_box_recall_iou0.25_pct"] == 100.0 and pooled["part_box_recall_iou0.25_pct"] == 0.0

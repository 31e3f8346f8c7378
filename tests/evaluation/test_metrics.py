"""Metrics of cuboidcli.evaluation on hand-built cases with known values."""

from __future__ import annotations

import math

import cv2
import numpy as np
import pytest
import torch

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.aggregate import aggregate, mean_std
from cuboidcli.evaluation.auc import AucStats, auc
from cuboidcli.evaluation.coverage import clip_corners_near, coverage_mask, fill_convex
from cuboidcli.evaluation.iou import box_iou, greedy_matches, intersection_volume
from cuboidcli.evaluation.metrics import frame_metrics
from cuboidcli.evaluation.oa import oa_distances, oa_sq_distances, oa_sq_prefix_distances, oa_sq_terms
from cuboidcli.evaluation.raycast import ray_coverage_mask, render_depth
from cuboidcli.geometry.kernels import oa_sq_distance
from cuboidcli.geometry.plan import convex_hull_2d
from cuboidcli.geometry.rotations import quaternion_to_matrix

NYU = Camera.preset("nyu")


def rot_z(deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def random_rotation(rng) -> np.ndarray:
    q = rng.normal(size=4)
    return quaternion_to_matrix(torch.tensor(q / np.linalg.norm(q))).numpy()


def random_boxes(rng, m: int, z=(1.0, 5.0)) -> list[Cuboid]:
    return [
        Cuboid(rng.uniform([-2, -2, z[0]], [2, 2, z[1]]), rng.uniform(0.1, 1.5, 3), random_rotation(rng))
        for _ in range(m)
    ]


# ---------------------------------------------------------------- OA-L2 distance


@pytest.mark.parametrize("seed", [0, 1, 2, 3])
def test_fused_oa_distance_matches_reference_kernel(seed):
    rng = np.random.default_rng(seed)
    boxes = random_boxes(rng, int(rng.integers(1, 9)))
    pts = rng.uniform([-3, -3, 0.3], [3, 3, 6], size=(5000, 3))
    # plus points on the surfaces and inside, where distances are small and occlusion matters most
    surf = np.concatenate([b.corners() * 0.999 + 0.001 * b.center for b in boxes])
    pts = np.concatenate([pts, surf, np.stack([b.center for b in boxes])])
    ours = oa_sq_distances(pts, boxes)
    c, a, r = (
        torch.tensor(np.stack(x))
        for x in ([b.center for b in boxes], [b.half_size for b in boxes], [b.rotation for b in boxes])
    )
    ref = oa_sq_distance(torch.tensor(pts), c, a, r).numpy()
    np.testing.assert_allclose(ours, ref, rtol=1e-10, atol=1e-12)
    assert (ref > 0).mean() > 0.5  # the cases are not trivial


@pytest.mark.parametrize("seed", [0, 1])
def test_prefix_oa_distances_equal_the_oa_distance_of_each_prefix_exactly(seed):
    rng = np.random.default_rng(seed)
    boxes = random_boxes(rng, 6)
    pts = rng.uniform([-3, -3, 0.3], [3, 3, 6], size=(4000, 3))
    pts = np.concatenate([pts, np.concatenate([b.corners() * 0.999 + 0.001 * b.center for b in boxes])])
    prefix = oa_sq_prefix_distances(pts, boxes)
    assert prefix.shape == (len(pts), 6)
    for k in range(1, 7):  # bit-identical, not just close: the last column IS the plain metric
        np.testing.assert_array_equal(prefix[:, k - 1], oa_sq_distances(pts, boxes[:k]))
    d_sq, occ_sq = oa_sq_terms(pts, boxes)
    for h in range(6):  # one cuboid: d_oa^2 = max(d^2, occlusion term)
        np.testing.assert_array_equal(
            np.maximum(d_sq[:, h], occ_sq[:, h]), oa_sq_distances(pts, boxes[h : h + 1])
        )
    subset = np.maximum(np.minimum(d_sq[:, 1], d_sq[:, 4]), np.maximum(occ_sq[:, 1], occ_sq[:, 4]))
    np.testing.assert_array_equal(subset, oa_sq_distances(pts, [boxes[1], boxes[4]]))
    assert (occ_sq > 0).mean() > 0.05 and (np.diff(prefix, axis=1) != 0).any()  # occlusion matters
    assert oa_sq_prefix_distances(pts, []).shape == (len(pts), 0)


def test_oa_distance_of_empty_set_is_infinite():
    assert np.isinf(oa_distances(np.ones((4, 3)), [])).all()


def test_rendered_room_matched_exactly_gives_zero_distance_and_full_auc():
    cam = NYU.scaled(0.25)  # 160x120
    room = Cuboid([0.0, -0.2, 2.5], [2.5, 1.5, 3.0], np.eye(3))  # the camera stands inside the room
    table = Cuboid([0.4, 0.8, 3.0], [0.5, 0.3, 0.4], rot_z(20.0))
    depth = render_depth(cam, [room, table])
    assert (depth > 0).all()
    m = frame_metrics("room", depth, cam, [room, table])
    assert m.n_points == cam.width * cam.height
    assert m.coverage == 1.0
    assert m.oa_all_m < 1e-6 and m.oa_covered_m < 1e-6
    assert m.auc[20.0].value > 0.9999 and m.auc[5.0].value > 0.9999


def test_floating_occluder_in_front_of_wall_gives_expected_occlusion_distance():
    cam = NYU.scaled(0.25)
    wall = Cuboid([0.0, 0.0, 3.05], [5.0, 5.0, 0.05], np.eye(3))  # front face on the plane z = 3
    floater = Cuboid([0.0, 0.0, 1.5], [0.25, 0.25, 0.25], np.eye(3))  # not in the data
    depth = render_depth(cam, [wall])
    np.testing.assert_allclose(depth, 3.0, atol=1e-5)
    pts = cam.backproject(depth.astype(np.float64)).reshape(-1, 3)
    dist = oa_distances(pts, [wall, floater])
    x, y = np.abs(pts[:, 0]), np.abs(pts[:, 1])
    behind = np.maximum(x, y) < 0.6 - 1e-3  # rays through the box: max(|x|,|y|) * 1.25 / 3 < 0.25
    free = np.maximum(x, y) > 0.6 + 1e-3
    assert behind.sum() > 100 and free.sum() > 100
    # the farthest occluding side is the front face z = 1.25: normal offset 1.75 m plus the tangential excess
    expected = np.sqrt(1.75**2 + np.maximum(x - 0.25, 0) ** 2 + np.maximum(y - 0.25, 0) ** 2)
    np.testing.assert_allclose(dist[behind], expected[behind], rtol=1e-6)
    assert dist[free].max() < 1e-6


# ---------------------------------------------------------------- coverage


def test_coverage_of_box_facing_camera_equals_analytic_hull_area():
    box = Cuboid([0.0, 0.0, 2.5], [0.5, 0.4, 0.5], np.eye(3))  # front face z = 2: its image is the hull
    analytic = (NYU.fx * 1.0 / 2.0) * (NYU.fy * 0.8 / 2.0)
    count = coverage_mask(NYU, [box]).sum()
    assert abs(count - analytic) / analytic < 0.01
    assert coverage_mask(NYU, [box]).mean() == pytest.approx(count / (640 * 480))


@pytest.mark.parametrize("seed", [0, 1])
def test_coverage_of_rotated_box_equals_hull_area_of_projected_corners(seed):
    rng = np.random.default_rng(seed)
    centre = rng.uniform([-0.3, -0.3, 3.0], [0.3, 0.3, 4.0])
    box = Cuboid(centre, rng.uniform(0.3, 0.8, 3), random_rotation(rng))
    uv, z = NYU.project(box.corners())
    assert (z > 0).all()
    hull_area = cv2.contourArea(cv2.convexHull(uv.astype(np.float32)))  # an independent hull
    count = coverage_mask(NYU, [box]).sum()
    assert abs(count - hull_area) / hull_area < 0.01


def test_coverage_clips_boxes_reaching_behind_the_camera():
    rng = np.random.default_rng(3)
    cam = NYU.scaled(0.25)
    for _ in range(6):
        boxes = random_boxes(rng, 2, z=(-1.0, 2.0))
        hull = coverage_mask(cam, boxes)
        rays = ray_coverage_mask(cam, boxes)  # pixels whose ray meets a box: the exact answer
        assert (hull != rays).sum() <= 2
    behind = Cuboid([0.0, 0.0, -3.0], [1.0, 1.0, 1.0], np.eye(3))
    around = Cuboid([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], np.eye(3))
    assert coverage_mask(cam, [behind]).sum() == 0
    assert coverage_mask(cam, [around]).all()


def test_near_plane_clipping_keeps_front_corners_and_adds_edge_crossings():
    box = Cuboid([0.0, 0.0, 0.0], [1.0, 1.0, 1.0], np.eye(3))
    verts = clip_corners_near(box.corners(), 0.5)
    assert len(verts) == 8  # four front corners plus four edges crossing z = 0.5
    assert np.allclose(np.sort(verts[:, 2]), [0.5] * 4 + [1.0] * 4)


def test_clamping_corners_behind_the_camera_would_be_wrong():
    """The research code's clamp (z -> 1e-3) mis-places corners behind the camera; clipping does not."""
    rng = np.random.default_rng(0)
    cam = NYU.scaled(0.25)
    wrong = 0
    for _ in range(40):
        box = random_boxes(rng, 1, z=(-1.0, 1.0))[0]
        truth = ray_coverage_mask(cam, [box])
        assert (coverage_mask(cam, [box]) != truth).sum() <= 2
        clamped = box.corners()
        clamped[:, 2] = np.maximum(clamped[:, 2], 1e-3)
        uv, _ = cam.project(clamped)
        wrong += (fill_convex(convex_hull_2d(uv), cam.width, cam.height) != truth).sum() > 2
    assert wrong >= 3


# ---------------------------------------------------------------- AUC


def test_auc_equals_hand_computed_trapezoid():
    d = np.array([0.05, 0.25, 0.01, 0.03])  # metres, unsorted
    # curve (0.01, 1/4) (0.03, 2/4) (0.05, 3/4) cut at (0.20, 3/4): 0.02*0.375 + 0.02*0.625 + 0.15*0.75
    assert auc(d, 0.20) == pytest.approx(0.1325 / 0.20)
    assert AucStats.of(d, 0.20).value == pytest.approx(0.1325 / 0.20)
    assert auc(d, 0.005) == 0.0
    assert auc(np.zeros(10), 0.05) == pytest.approx(1.0)


def test_pooled_auc_statistics_equal_auc_of_all_points():
    rng = np.random.default_rng(0)
    parts = [rng.exponential(0.1, 1000), rng.exponential(0.3, 500), np.full(200, np.inf)]
    for x in (0.2, 0.05):
        pooled = AucStats.of(parts[0], x).merge(AucStats.of(parts[1], x)).merge(AucStats.of(parts[2], x))
        assert pooled.value == pytest.approx(auc(np.concatenate(parts), x), rel=1e-12)


# ---------------------------------------------------------------- aggregation


def test_aggregate_pools_auc_and_counts_empty_fits_in_the_oa_mean():
    cam = NYU.scaled(0.125)  # 80x60
    wall = Cuboid([0.0, 0.0, 3.05], [5.0, 5.0, 0.05], np.eye(3))
    depth = render_depth(cam, [wall])
    exact = frame_metrics("a", depth, cam, [wall], time_s=1.0)
    behind_wall = Cuboid([0.0, 0.0, 3.15], [5.0, 5.0, 0.05], np.eye(3))
    shifted = frame_metrics("b", depth, cam, [behind_wall], time_s=3.0)
    empty = frame_metrics("c", depth, cam, [], time_s=0.5)
    assert shifted.oa_all_m == pytest.approx(0.1, abs=1e-6)  # the wall is 10 cm in front of the box
    # no cuboid: each point is as far from the abstraction as from the camera; nothing is covered
    u, v = np.meshgrid(np.arange(cam.width), np.arange(cam.height))
    ray = np.sqrt(((u - cam.cx) / cam.fx) ** 2 + ((v - cam.cy) / cam.fy) ** 2 + 1.0)
    to_camera = float((3.0 * ray).mean())  # the wall's face is the plane z = 3 m over the whole image
    assert empty.oa_all_m == pytest.approx(to_camera, rel=1e-5) and to_camera > 3.0
    assert math.isnan(empty.oa_covered_m) and empty.coverage == 0.0
    agg = aggregate([exact, shifted, empty])
    assert agg["time_s"] == pytest.approx(1.5)
    assert agg["cuboids"] == pytest.approx(2 / 3)
    # all three frames count in the OA mean; the covered mean skips the frame without covered points
    assert agg["oa_all_cm"] == pytest.approx((0.0 + 10.0 + 100.0 * to_camera) / 3, abs=1e-3)
    assert agg["oa_covered_cm"] == pytest.approx(5.0, abs=1e-4)
    assert agg["frames_without_cuboids"] == 1
    # pooled: a third of the points at 0 cm, a third at 10 cm, a third infinite
    assert agg["auc20cm_pct"] == pytest.approx(100 * (1 + 0.5) / 3, abs=0.01)
    assert agg["auc5cm_pct"] == pytest.approx(100 / 3, abs=0.01)
    summary = mean_std([agg, {**agg, "cuboids": 4 / 3}])
    assert summary["cuboids"] == pytest.approx((1.0, 1 / 3))


# ---------------------------------------------------------------- parsimony curve


def _room_frames():
    """Two rendered views of a room with a table and a cabinet (80x60), cuboids in selection order; the
    second view's fit misses the cabinet and a third fit is empty."""
    cam = NYU.scaled(0.125)
    room = Cuboid([0.0, -0.2, 2.5], [2.5, 1.5, 3.0], np.eye(3))
    table = Cuboid([0.4, 0.8, 3.0], [0.5, 0.3, 0.4], rot_z(20.0))
    cabinet = Cuboid([-1.2, 0.6, 3.8], [0.4, 0.6, 0.3], np.eye(3))
    off = Cuboid([0.3, 0.0, 2.0], [0.2, 0.2, 0.2], np.eye(3))  # not in the data: hides part of the room
    depth = render_depth(cam, [room, table, cabinet])
    return cam, depth, [[table, off, room, cabinet], [room, table], []]


def test_parsimony_curve_of_a_frame_ends_at_the_plain_values_and_starts_at_the_first_cuboid():
    cam, depth, (fit, _, _) = _room_frames()
    m = frame_metrics("a", depth, cam, fit, parsimony_k=6)
    plain = frame_metrics("a", depth, cam, fit)
    assert len(m.prefix_coverage) == 6 and all(len(v) == 6 for v in m.prefix_auc.values())
    for cm in (20.0, 5.0):
        assert m.prefix_auc[cm][-1].value == plain.auc[cm].value == m.auc[cm].value
        assert m.prefix_auc[cm][3].value == plain.auc[cm].value  # k = 4 = |M|: all cuboids
        for k in (1, 2, 3):  # each prefix is the set of its first k cuboids, evaluated alone
            alone = frame_metrics("a", depth, cam, fit[:k])
            assert m.prefix_auc[cm][k - 1].value == alone.auc[cm].value
            assert m.prefix_coverage[k - 1] == alone.coverage
    assert m.prefix_coverage[-1] == plain.coverage == m.coverage
    assert m.oa_all_m == plain.oa_all_m and m.oa_covered_m == plain.oa_covered_m
    assert np.all(np.diff(m.prefix_coverage) >= 0) and m.prefix_coverage[0] < m.prefix_coverage[-1]
    auc20 = [s.value for s in m.prefix_auc[20.0]]
    assert auc20[1] < auc20[2] < auc20[3]
    # AUC need not grow with k: the occluder "off" hides part of the room, which then costs AUC
    without_off = frame_metrics("a", depth, cam, [fit[0], fit[2]]).auc[20.0].value
    assert auc20[2] < without_off - 0.01


def test_pooled_parsimony_curve_equals_the_aggregate_of_each_prefix():
    cam, depth, fits = _room_frames()
    frames = [frame_metrics(f"f{i}", depth, cam, fit, parsimony_k=5) for i, fit in enumerate(fits)]
    agg = aggregate(frames)
    curve = agg["parsimony"]
    assert curve["k"] == [1, 2, 3, 4, 5] and set(curve) == {"k", "auc20cm_pct", "auc5cm_pct", "coverage_pct"}
    for k in range(1, 6):  # frames with fewer than k cuboids use all of theirs; the empty one stays empty
        prefix = aggregate([frame_metrics(f"f{i}", depth, cam, fit[:k]) for i, fit in enumerate(fits)])
        for key in ("auc20cm_pct", "auc5cm_pct", "coverage_pct"):
            assert curve[key][k - 1] == pytest.approx(prefix[key], rel=1e-12, abs=1e-12)
    for key in ("auc20cm_pct", "auc5cm_pct", "coverage_pct"):
        assert curve[key][-1] == pytest.approx(agg[key], rel=1e-12)
    assert np.all(np.diff(curve["coverage_pct"]) >= 0)
    assert "parsimony" not in aggregate(frames, curves=False)
    assert "parsimony" not in aggregate([frame_metrics("p", depth, cam, fits[0])])  # not requested
    # over runs: element-wise mean and population std
    other = {**agg, "parsimony": {**curve, "coverage_pct": [c + 2.0 for c in curve["coverage_pct"]]}}
    mean, std = mean_std([agg, other])["parsimony"]
    assert mean["k"] == curve["k"]
    np.testing.assert_allclose(mean["coverage_pct"], np.array(curve["coverage_pct"]) + 1.0)
    np.testing.assert_allclose(std["coverage_pct"], 1.0)
    np.testing.assert_allclose(std["auc20cm_pct"], 0.0)


def test_parsimony_curve_longer_than_max_cuboids_when_a_frame_has_more():
    cam, depth, (fit, _, empty) = _room_frames()
    m = frame_metrics("a", depth, cam, fit, parsimony_k=2)
    assert len(m.prefix_coverage) == 4  # never cut short of the frame's own cuboids
    e = frame_metrics("e", depth, cam, empty, parsimony_k=2)
    assert e.prefix_coverage == [0.0, 0.0] and all(s.value == 0.0 for s in e.prefix_auc[20.0])
    assert aggregate([m, e])["parsimony"]["k"] == [1, 2, 3, 4]
    # a frame with fewer cuboids is extended with its full value when another frame sets a longer curve
    two = frame_metrics("b", depth, cam, fit[:2], parsimony_k=2)
    curve = aggregate([m, two])["parsimony"]
    for k in range(1, 5):
        prefix = aggregate(
            [frame_metrics("a", depth, cam, fit[:k]), frame_metrics("b", depth, cam, fit[: min(k, 2)])]
        )
        assert curve["auc20cm_pct"][k - 1] == pytest.approx(prefix["auc20cm_pct"], rel=1e-12)
        assert curve["coverage_pct"][k - 1] == pytest.approx(prefix["coverage_pct"], rel=1e-12)


# ---------------------------------------------------------------- IoU and matching


def test_iou_of_unit_cubes_offset_by_half_along_x_is_one_third():
    a = Cuboid([0, 0, 0], [0.5, 0.5, 0.5], np.eye(3))
    b = Cuboid([0.5, 0, 0], [0.5, 0.5, 0.5], np.eye(3))
    assert box_iou(a, b) == pytest.approx(1 / 3, abs=1e-12)
    assert box_iou(a, a) == pytest.approx(1.0, abs=1e-12)
    assert box_iou(a, Cuboid([2, 0, 0], [0.5, 0.5, 0.5], np.eye(3))) == 0.0


def test_iou_of_cube_rotated_45_degrees_about_z_with_itself():
    a = Cuboid([0, 0, 0], [0.5, 0.5, 0.5], np.eye(3))
    b = Cuboid([0, 0, 0], [0.5, 0.5, 0.5], rot_z(45.0))
    # the cross-section is a regular octagon of apothem 1/2: area 2 tan(pi/8) = 2 (sqrt 2 - 1)
    inter = 2 * (math.sqrt(2) - 1)
    assert intersection_volume(a, b) == pytest.approx(inter, abs=1e-12)
    assert box_iou(a, b) == pytest.approx(1 / math.sqrt(2), abs=1e-12)


def test_iou_of_nested_and_general_boxes():
    big = Cuboid([0, 0, 0], [1.0, 1.0, 1.0], rot_z(30.0))
    small = Cuboid([0.1, 0, 0], [0.2, 0.3, 0.4], rot_z(-10.0))
    assert box_iou(big, small) == pytest.approx(small.volume() / big.volume(), abs=1e-12)
    rng = np.random.default_rng(4)
    a = Cuboid(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.3, 0.8, 3), random_rotation(rng))
    b = Cuboid(rng.uniform(-0.3, 0.3, 3), rng.uniform(0.3, 0.8, 3), random_rotation(rng))
    pts = rng.uniform(-1.5, 1.5, size=(400_000, 3))

    def inside(box):
        return (np.abs((pts - box.center) @ box.rotation) <= box.half_size).all(axis=1)

    monte_carlo = (inside(a) & inside(b)).mean() * 27.0
    assert intersection_volume(a, b) == pytest.approx(monte_carlo, rel=0.03)
    assert intersection_volume(a, b) == pytest.approx(intersection_volume(b, a), rel=1e-12)


def test_greedy_matching_is_one_to_one_and_takes_best_first():
    ious = np.array([[0.9, 0.6, 0.0], [0.8, 0.3, 0.0], [0.0, 0.0, 0.2]])
    assert sorted(greedy_matches(ious, 0.25)) == [(0, 0), (1, 1)]
    assert greedy_matches(ious, 0.5) == [(0, 0)]


def test_the_recall_curve_counts_points_within_each_distance_and_pools_over_frames():
    from cuboidcli.evaluation.auc import RECALL_CURVE_CM, pooled_recall_pct, recall_counts

    d = np.array([0.0, 0.004, 0.01, 0.019, 0.2, np.inf])
    counts = recall_counts(d)
    assert counts[RECALL_CURVE_CM.index(0.0)] == 1 and counts[RECALL_CURVE_CM.index(1.0)] == 3
    assert counts[RECALL_CURVE_CM.index(2.0)] == 4 and counts[-1] == 5  # 50 cm; inf is never within
    assert counts == sorted(counts)
    # the curve's area up to X over X is the AUC at X, within the 1 cm sampling of the curve
    rng = np.random.default_rng(0)
    many = rng.exponential(0.05, 5000)
    curve = np.array(recall_counts(many)) / many.size
    area = np.trapezoid(curve[:21], np.array(RECALL_CURVE_CM[:21]) / 100) / 0.2
    assert area == pytest.approx(auc(many, 0.2), abs=0.01)

    class Frame:  # what pooling reads of a FrameMetrics
        def __init__(self, dist):
            self.recall_counts, self.n_points = recall_counts(dist), len(dist)

    pooled = pooled_recall_pct([Frame(d), Frame(np.full(4, 0.001))])
    assert pooled[RECALL_CURVE_CM.index(1.0)] == pytest.approx(100.0 * (3 + 4) / 10)
    assert pooled_recall_pct([]) is None

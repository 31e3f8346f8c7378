"""The room plausibility checks at their edges: the size limits and point count exactly at the boundary, the
unit a refusal suggests where two units compete, malformed point arrays, and normals a little off unit
length."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.io.scan import MIN_POINTS, PointCloud
from cuboidcli.load.units import MAX_DIAGONAL_M, MIN_DIAGONAL_M, check_cloud
from tests.io.test_sequence import refused


def cloud_of_diagonal(diagonal: float, n: int = MIN_POINTS, normals=None) -> PointCloud:
    """``n`` points on the segment from the origin to (d, d, d) / sqrt(3): a bounding-box diagonal of
    exactly ``diagonal`` (up to rounding)."""
    t = np.linspace(0.0, 1.0, n)[:, None]
    points = t * np.full(3, diagonal / np.sqrt(3.0))
    return PointCloud(points, normals=normals, meta={"path": "room.npy"})


def test_the_size_limits_hold_at_their_boundaries():
    assert (MIN_DIAGONAL_M, MAX_DIAGONAL_M) == (0.3, 200.0)
    for inside in (MIN_DIAGONAL_M * 1.0001, 5.0, MAX_DIAGONAL_M * 0.9999):
        cloud = check_cloud(cloud_of_diagonal(inside), "m")
        assert cloud.meta["diagonal_m"] == round(inside, 4) and cloud.meta["points"] == MIN_POINTS
    refused(lambda: check_cloud(cloud_of_diagonal(MAX_DIAGONAL_M * 1.001), "m"), "200 m across", "too large")
    refused(
        lambda: check_cloud(cloud_of_diagonal(MIN_DIAGONAL_M * 0.999), "m"), "299.7 mm across", "too small"
    )
    # a small box is said in millimetres with one decimal, a large one in whole metres
    refused(lambda: check_cloud(cloud_of_diagonal(0.012449), "m"), "room.npy is 12.4 mm across with --unit m")
    refused(lambda: check_cloud(cloud_of_diagonal(1234.4), "cm"), "room.npy is 1234 m across with --unit cm")


def test_the_size_limits_are_inclusive():
    for diagonal in (MIN_DIAGONAL_M, MAX_DIAGONAL_M):  # a segment along x: its diagonal is exact
        points = np.c_[np.linspace(0.0, diagonal, MIN_POINTS), np.zeros((MIN_POINTS, 2))]
        assert check_cloud(PointCloud(points, meta={"path": "x.npy"}), "m").meta["diagonal_m"] == diagonal


def test_the_recorded_diagonal_has_four_decimals():
    cloud = check_cloud(cloud_of_diagonal(3.123456), "m")
    assert cloud.meta["diagonal_m"] == 3.1235


def test_the_fewest_points_a_room_may_have():
    assert len(check_cloud(cloud_of_diagonal(4.0, n=MIN_POINTS), "m").points) == MIN_POINTS
    refused(
        lambda: check_cloud(cloud_of_diagonal(4.0, n=MIN_POINTS - 1), "m"), f"has {MIN_POINTS - 1} points"
    )


def test_the_suggested_unit_is_the_one_that_makes_a_room_a_few_metres_across():
    # 1897 units: 18.97 m as centimetres, 1.897 m as millimetres; 1.897 m is nearer a room's 5 m
    # (by ratio) than 18.97 m, and both are plausible sizes
    refused(lambda: check_cloud(cloud_of_diagonal(1897.0), "m"), "it looks like millimetres: pass --unit mm")
    # 1200 units: 12 m as centimetres is nearer 5 m than 1.2 m as millimetres
    refused(lambda: check_cloud(cloud_of_diagonal(1200.0), "m"), "it looks like centimetres: pass --unit cm")
    # 400 units of metres: only centimetres (4 m) is room-sized... and millimetres (0.4 m) too; 4 m wins
    refused(lambda: check_cloud(cloud_of_diagonal(400.0), "m"), "pass --unit cm")
    # 0.01 m read as millimetres: 10 mm; as metres 10 m (plausible), as centimetres 1 m
    refused(lambda: check_cloud(cloud_of_diagonal(0.01), "mm"), "it looks like metres: pass --unit m")
    # read as millimetres, a box 4 mm across is 40 cm as centimetres and 4 m as metres
    refused(lambda: check_cloud(cloud_of_diagonal(0.004), "mm"), "pass --unit m")
    # nothing makes 1e9 units a room: the unit is only said to be checked
    refused(
        lambda: check_cloud(cloud_of_diagonal(1e9), "m"),
        "too large for a room; check --unit (coordinates read as",
    )


def test_points_of_the_wrong_shape_are_refused():
    for points in (np.zeros((200, 2)), np.zeros((200, 4)), np.zeros(600), np.zeros((2, 100, 3))):
        refused(lambda p=points: check_cloud(PointCloud(p, meta={"path": "x.npy"}), "m"), "expected (N, 3)")


def test_normals_a_little_off_unit_length_are_dropped_with_a_warning():
    unit = np.tile([0.0, 0.0, 1.0], (MIN_POINTS, 1))
    kept = check_cloud(cloud_of_diagonal(4.0, normals=unit * (1 + 5e-4)), "m")
    assert kept.normals is not None and kept.warnings == []
    for scale in (0.98, 1.0012, 1.02):  # 0.98: 2 % short, which squaring the error would let through
        normals = unit.copy()
        normals[:7] *= scale
        cloud = check_cloud(cloud_of_diagonal(4.0, normals=normals), "m")
        assert cloud.normals is None
        assert cloud.warnings == [f"7 of {MIN_POINTS} normals are zero or not finite; normals dropped"]


@pytest.mark.parametrize("bad", [np.nan, np.inf, -np.inf])
def test_a_single_non_finite_coordinate_is_refused(bad):
    cloud = cloud_of_diagonal(4.0)
    cloud.points[3, 1] = bad
    refused(lambda: check_cloud(cloud, "m"), f"1 of {MIN_POINTS} points have NaN or inf coordinates")

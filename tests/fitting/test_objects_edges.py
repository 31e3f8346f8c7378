"""Edges of a room's whole-object grouping (cuboidcli.fitting.objects, cuboidcli.fitting.not_objects):
scores worked out by hand from object_score's formula, boxes of known extent, the floor under a tilted or
stepped floor, and each threshold just inside and just outside."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting import objects
from cuboidcli.fitting.floors import floor_heights
from cuboidcli.fitting.not_objects import (
    FLOOR_PATCH_LAYER_M,
    FLOOR_PATCH_MEDIAN_M,
    FLOOR_PATCH_TOP_M,
    floor_to_ceiling,
    is_bent_floor,
    is_floor_patch,
    near_wall,
    on_wall,
    wall_coloured,
)
from cuboidcli.fitting.objects import (
    FLOOR_CLEARANCE_M,
    SHELL_CLEARANCE,
    SceneObject,
    group_objects,
    object_score,
)

VOXEL = 0.035
UP = np.array([0.0, 0.0, 1.0])
#: The lowest layer of what stands on the floor in these rooms, clear of the floor's 11 cm.
ABOVE = 0.14


def _grid(lo, hi, step=VOXEL):
    spans = zip(lo, hi, strict=True)
    axes = [np.arange(a, b + 1e-9, step) if b - a > 1e-9 else np.array([a]) for a, b in spans]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def _yaw(theta):
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _about_x(t):
    c, s = math.cos(t), math.sin(t)
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


def _extent(box: Cuboid):
    corners = box.corners()
    return corners.min(0), corners.max(0)


FLOOR = Cuboid([1.5, 1.5, -0.02], [1.5, 1.5, 0.02], np.eye(3), kind="floor")  # top face at z = 0
#: A wall whose face is at x = 0.85, 10 cm from what stands at x = 1.
WALL_NEAR = Cuboid([0.8, 1.5, 1.3], [0.05, 1.5, 1.3], np.eye(3), kind="wall")


def _on_floor(*parts, labels=None):
    """Floor points (cuboid 0, 3 m x 3 m at z = 0, every other voxel) and the parts, unlabelled unless
    ``labels`` gives one label per part."""
    floor = _grid((0, 0, 0), (3, 3, 0), 2 * VOXEL)
    labels = labels or [-1] * len(parts)
    pts = np.concatenate([floor, *parts])
    lab = np.concatenate(
        [np.zeros(len(floor))] + [np.full(len(p), k) for p, k in zip(parts, labels, strict=True)]
    )
    return pts, lab.astype(np.int32)


# --- object_score, by hand -------------------------------------------------------------------------------


def test_object_score_by_hand():
    """Voxel 0.5 m, so the score's cells are 1 m; a 4 x 2 x 3 m box at lo = (10, -5, 1) with four points at
    cell centres and one on the box's far corner (clipped into the last cell).

    top view (4 x 2 cells): (0,0) (0,1) (2,0) (3,1) (3,1) -> 4 / 8; x-z side (4 x 3): (0,0) (0,0) (2,0) (3,2)
    (3,2) -> 3 / 12; y-z side (2 x 3): (0,0) (1,0) (0,0) (1,2) (1,2) -> 3 / 6, the better side.
    fill = (4/8 + 3/6) / 2 = 0.5; support = 1 - exp(-5 / 400)."""
    lo, hi = np.array([10.0, -5.0, 1.0]), np.array([14.0, -3.0, 4.0])
    cells = np.array([[0.5, 0.5, 0.5], [0.5, 1.5, 0.5], [2.5, 0.5, 0.5], [3.5, 1.5, 2.5], [4.0, 2.0, 3.0]])
    local = lo + cells
    support = 1.0 - math.exp(-5 / 400)
    assert object_score(local, lo, hi, 0.5, True) == pytest.approx(0.5 * support, rel=1e-12)
    assert object_score(local, lo, hi, 0.5, False) == pytest.approx(0.7 * 0.5 * support, rel=1e-12)
    assert object_score(local[:0], lo, hi, 0.5, True) == 0.0
    # x and y swapped: the better side is now the x-z view, the score the same
    swap = [1, 0, 2]
    assert object_score(local[:, swap], lo[swap], hi[swap], 0.5, True) == pytest.approx(
        0.5 * support, rel=1e-12
    )


def test_object_score_of_a_full_box_and_of_a_flat_one():
    """Points in every cell: fill 1, the score is the support alone; a box of no height (a flat patch)
    has one row of cells in its side views."""
    lo, hi = np.zeros(3), np.array([2.0, 1.0, 1.0])
    local = _grid((0.25, 0.25, 0.25), (1.75, 0.75, 0.75), 0.5)  # 4 x 2 x 2 points, voxel 0.25: 0.5 m cells
    assert len(local) == 16
    assert object_score(local, lo, hi, 0.25, True) == pytest.approx(1.0 - math.exp(-16 / 400), rel=1e-12)
    flat = np.array([[0.25, 0.25, 0.0], [1.25, 0.25, 0.0]])
    # top 2 of 4 x 2 cells, x-z side 2 of 4 x 1, y-z side 1 of 2 x 1: fill (2/8 + 2/4) / 2
    score = object_score(flat, lo, np.array([2.0, 1.0, 0.0]), 0.25, True)
    assert score == pytest.approx(0.375 * (1.0 - math.exp(-2 / 400)), rel=1e-12)


def test_coverage_counts_each_cell_once():
    # 3 x 2 cells of 1 m: (0,0) (0,1) (2,0) and a point past the far corner, clipped into (2,1)
    uv = np.array([[0.5, 0.5], [0.5, 1.5], [2.5, 0.5], [0.6, 0.4], [9.0, 9.0]])
    assert objects._coverage(uv, np.array([3.0, 2.0]), 1.0) == pytest.approx(4 / 6)
    assert objects._coverage(uv[:1] - 5.0, np.array([3.0, 2.0]), 1.0) == pytest.approx(
        1 / 6
    )  # clipped to (0,0)
    assert objects._coverage(uv[:1], np.array([0.0, 0.0]), 1.0) == 1.0  # a point box is one cell


# --- the small geometry helpers --------------------------------------------------------------------------


def test_outside_distance_of_a_turned_box():
    box = Cuboid([1.0, 2.0, 0.5], [0.4, 0.2, 0.5], _yaw(math.pi / 2))  # its x along the world's y
    pts = np.array([[1.0, 2.0, 0.5], [1.0, 2.5, 0.5], [1.5, 2.0, 0.5], [1.5, 2.7, 1.5], [0.7, 1.5, 0.1]])
    d = objects._outside_distance(pts, box)
    np.testing.assert_allclose(
        d, [0.0, 0.1, 0.3, math.sqrt(0.3**2 + 0.3**2 + 0.5**2), math.sqrt(0.02)], atol=1e-12
    )


def test_yaw_of_a_boxs_most_horizontal_axis():
    assert objects._yaw(_yaw(0.3)) == pytest.approx(0.3)
    tilted = _yaw(0.3) @ np.array(
        [[math.cos(0.4), 0.0, math.sin(0.4)], [0.0, 1.0, 0.0], [-math.sin(0.4), 0.0, math.cos(0.4)]]
    )  # its first axis tipped 0.4 rad out of level: the second axis is the level one
    assert objects._yaw(tilted) == pytest.approx(0.3 + math.pi / 2)
    m = objects._yaw_matrix(0.3)
    np.testing.assert_allclose(m, _yaw(0.3), atol=1e-15)


def test_principal_yaw_of_points_along_a_line():
    t = np.linspace(-1.0, 1.0, 21)
    xy = np.stack([5.0 + 2.0 * t * math.cos(0.4), 3.0 + 2.0 * t * math.sin(0.4)], 1)
    xy += 0.05 * np.stack([-math.sin(0.4) * (-1) ** np.arange(21), math.cos(0.4) * (-1) ** np.arange(21)], 1)
    theta = objects._principal_yaw(xy)
    assert math.tan(theta) == pytest.approx(math.tan(0.4), rel=1e-9)


# --- the floor under each point ---------------------------------------------------------------------------


@pytest.mark.parametrize("flip", [False, True])
def test_floor_height_under_a_tilted_floor(flip):
    """A floor 2 cm thick tilted 0.1 rad about x: its top plane n . p = 0.01 with n = (0, -sin t, cos t), so
    z = (0.01 + y sin t) / cos t; the same with its thin axis pointing down."""
    t = 0.1
    rot = _about_x(t) @ (np.diag([1.0, -1.0, -1.0]) if flip else np.eye(3))
    floor = Cuboid([0.0, 0.0, 0.0], [2.0, 2.0, 0.01], rot, kind="floor")
    level = np.array([[0.3, -1.0, 1.0], [-0.5, 0.0, 1.0], [1.0, 1.5, 1.0]])
    expect = (0.01 + level[:, 1] * math.sin(t)) / math.cos(t)
    np.testing.assert_allclose(floor_heights(level, [floor], np.eye(3)), expect, atol=1e-12)
    # the same floor seen in a frame turned about the up axis: R turns level to world
    R = _yaw(0.7)
    turned = Cuboid(R @ floor.center, floor.half_size, R @ rot, kind="floor")
    np.testing.assert_allclose(floor_heights(level, [turned], R), expect, atol=1e-12)


def test_floor_height_of_a_steep_floor_is_bounded():
    """Tilted 70 degrees: the slope is taken with n_z at least 0.5, z = top_z + 2 sin t (y - top_y)."""
    t = math.radians(70)
    floor = Cuboid([0.0, 0.0, 0.0], [2.0, 2.0, 0.01], _about_x(t), kind="floor")
    level = np.array([[0.0, 0.5, 1.0], [0.0, -0.5, 1.0]])
    top = np.array([0.0, -0.01 * math.sin(t), 0.01 * math.cos(t)])
    expect = top[2] + 2.0 * math.sin(t) * (level[:, 1] - top[1])
    np.testing.assert_allclose(floor_heights(level, [floor], np.eye(3)), expect, atol=1e-12)


def test_floor_reach_takes_the_highest_floor_within_30_cm():
    """Two floors, x in [0, 2] at 0 and x in [2.5, 4.5] at 0.3: a point 0.2 / 0.29 m from them stands on the
    higher, one 0.19 / 0.31 m from them on the lower (the nearest)."""
    low = Cuboid([1.0, 1.0, -0.01], [1.0, 1.0, 0.01], np.eye(3), kind="floor")
    high = Cuboid([3.5, 1.0, 0.29], [1.0, 1.0, 0.01], np.eye(3), kind="floor")
    level = np.array(
        [[2.21, 1.0, 1.0], [2.19, 1.0, 1.0], [1.0, 1.0, 1.0], [2.35, 1.0, 1.0], [2.35, 1.5, 1.0]]
    )
    np.testing.assert_allclose(
        floor_heights(level, [low, high], np.eye(3)), [0.3, 0.0, 0.0, 0.3, 0.3], atol=1e-12
    )
    # beside the floors (off their y range): 0.233 / 0.307 m and 0.455 / 0.494 m from them, the lower
    side = np.array([[2.21, 2.1, 1.0], [2.21, 2.4, 1.0]])
    np.testing.assert_allclose(floor_heights(side, [low, high], np.eye(3)), [0.0, 0.0], atol=1e-12)


# --- group_objects ----------------------------------------------------------------------------------------


def test_labels_must_match_the_points():
    with pytest.raises(ValueError, match="3 labels for 2 points"):
        group_objects(np.zeros((2, 3)), np.zeros(3, dtype=np.int32), [], UP, VOXEL)


def _box_pts(x0, y0, z0, w, d, h):
    return _grid((x0, y0, z0), (x0 + w, y0 + d, z0 + h))


def test_a_box_on_the_floor_its_extent_points_and_score():
    """A crate of unlabelled points 0.2 x 0.1 x 0.2 m (7 x 4 x 6 points from z = 0.14): its box spans the
    points grown by half a voxel and stands on the floor (its lowest point just over the floor's
    clearance)."""
    crate = _box_pts(1.0, 1.0, ABOVE, 6 * VOXEL, 3 * VOXEL, 5 * VOXEL)
    assert len(crate) == 7 * 4 * 6
    pts, lab = _on_floor(crate)
    (o,) = group_objects(pts, lab, [FLOOR], UP, VOXEL)
    assert o.points == 168 and o.cuboids == ()
    lo, hi = _extent(o.box)
    np.testing.assert_allclose(lo, [1.0 - VOXEL / 2, 1.0 - VOXEL / 2, 0.0], atol=1e-9)
    np.testing.assert_allclose(hi, crate.max(0) + VOXEL / 2, atol=1e-9)
    assert o.box.kind == "object"
    d = o.to_dict(3)
    assert d["id"] == 3 and d["points"] == 168 and d["cuboids"] == []
    np.testing.assert_allclose(d["center"], o.box.center, atol=1e-6)
    assert 0.0 < o.score < 1.0 - math.exp(-168 / 400) + 1e-12


@pytest.mark.parametrize(("z0", "grounded"), [(0.1625, True), (0.1725, False)])
def test_a_box_within_three_voxels_of_the_floor_stands_on_it(z0, grounded, monkeypatch):
    """The box's bottom (half a voxel under its lowest points) 14.5 or 15.5 cm up, against 3 voxels (10.5
    cm) and the 4.35 cm by which the floor's clearance (11 cm) exceeds 1.9 voxels: what stands on the
    floor starts that much higher. A low floating box is then extended to the floor as furniture on unseen
    legs (STAND_LOW_M), but its score stays that of a floating box."""
    import cuboidcli.fitting.objects as objects_module

    crate = _box_pts(1.0, 1.0, z0, 6 * VOXEL, 3 * VOXEL, 5 * VOXEL)
    pts, lab = _on_floor(crate)
    (o,) = group_objects(pts, lab, [FLOOR], UP, VOXEL)
    assert _extent(o.box)[0][2] == pytest.approx(0.0, abs=1e-9)
    monkeypatch.setattr(objects_module, "STAND_LOW_M", -1.0)
    (bare,) = group_objects(pts, lab, [FLOOR], UP, VOXEL)
    assert bare.score == o.score
    lo, _ = _extent(bare.box)
    assert lo[2] == pytest.approx(0.0 if grounded else z0 - VOXEL / 2, abs=1e-9)
    # the score counts the box as standing (x 1) or floating (x 0.7): the same points, scored by hand
    local = crate - (crate.min(0) - VOXEL / 2)
    size = crate.max(0) - crate.min(0) + VOXEL
    if grounded:
        local[:, 2] += z0 - VOXEL / 2
        size[2] += z0 - VOXEL / 2
    expect = object_score(local, np.zeros(3), size, VOXEL, grounded)
    assert o.score == pytest.approx(expect, rel=1e-9)
    assert (0.7 * o.score if grounded else o.score / 0.7) == pytest.approx(
        object_score(local, np.zeros(3), size, VOXEL, not grounded), rel=1e-9
    )


@pytest.mark.parametrize(("z0", "kept"), [(0.111, 168), (0.109, 140)])
def test_points_within_the_shell_clearance_of_the_floor_are_the_floors(z0, kept):
    """The crate's lowest layer (28 points) 11.1 cm above the floor is the crate's, 10.9 cm up the floor's:
    at a voxel of 3.5 cm the floor's clearance is its 11 cm, not 1.9 voxels (6.65 cm), a wall's."""
    assert FLOOR_CLEARANCE_M == 0.11 > SHELL_CLEARANCE * VOXEL
    crate = _box_pts(1.0, 1.0, z0, 6 * VOXEL, 3 * VOXEL, 5 * VOXEL)
    pts, lab = _on_floor(crate)
    (o,) = group_objects(pts, lab, [FLOOR], UP, VOXEL)
    assert o.points == kept


@pytest.mark.parametrize(("z0", "kept"), [(0.11, 20), (0.1101, 21)])
def test_a_point_exactly_at_the_floor_s_clearance_is_the_floors(z0, kept):
    """A column of 21 points half a metre past the floor cuboid's edge (only its height counts): its lowest
    point exactly 11 cm up is the floor's, 0.1 mm higher the column's."""
    column = np.array([[3.5, 1.0, z0 + VOXEL * i] for i in range(21)])
    (o,) = group_objects(column, np.full(21, -1), [FLOOR], UP, VOXEL)
    assert o.points == kept


@pytest.mark.parametrize(("z", "found"), [(0.12, 0), (0.14, 0), (0.15, 1)])
def test_a_flat_layer_just_over_the_floor_s_clearance_is_the_floor(z, found):
    """A level layer of 15 x 15 points (0.5 m square) 12 or 14 cm up, 1-3 cm over the floor's clearance, is
    a patch of a floor that steps (:func:`~cuboidcli.fitting.not_objects.is_floor_patch`); 15 cm up it is
    the lid of something low."""
    layer = _grid((1.0, 1.0, z), (1.49, 1.49, z))
    assert len(layer) == 225
    pts, lab = _on_floor(layer)
    assert len(group_objects(pts, lab, [FLOOR], UP, VOXEL)) == found


@pytest.mark.parametrize(("gap", "kept"), [(0.0675, 168), (0.0655, 144)])
def test_points_within_the_shell_clearance_of_a_wall_are_the_walls(gap, kept):
    """The same crate standing against a wall (face at x = 2): its layer nearest the wall stays only when it
    is more than 6.65 cm (1.9 voxels) from it (24 of 168 points); the wall's own points never count."""
    wall = Cuboid([2.02, 1.5, 1.0], [0.02, 1.5, 1.0], np.eye(3), kind="wall")
    crate = _box_pts(2.0 - gap - 6 * VOXEL, 1.0, ABOVE, 6 * VOXEL, 3 * VOXEL, 5 * VOXEL)
    wall_pts = _grid((2.0, 0.2, 0.1), (2.0, 2.8, 1.5), 2 * VOXEL)
    pts, lab = _on_floor(crate, wall_pts, labels=[-1, 1])
    (o,) = group_objects(pts, lab, [FLOOR, wall], UP, VOXEL)
    assert o.points == kept


def test_without_a_floor_cuboid_the_floor_is_the_lowest_percent_of_points():
    crate = _box_pts(1.0, 1.0, ABOVE, 6 * VOXEL, 3 * VOXEL, 5 * VOXEL)
    pts, lab = _on_floor(crate)
    lab[lab == 0] = -1  # the floor's points are there, but no floor cuboid
    (o,) = group_objects(pts, lab, [], UP, VOXEL)
    assert o.points == 168
    lo, _ = _extent(o.box)
    assert lo[2] == pytest.approx(0.0, abs=1e-9)


@pytest.mark.parametrize(("n_free", "found"), [(20, 1), (19, 0)])
def test_unexplained_points_are_an_object_from_20_on(n_free, found):
    column = np.array([[1.0, 1.0, 0.3 + VOXEL * i] for i in range(n_free)])
    pts, lab = _on_floor(column)
    assert len(group_objects(pts, lab, [FLOOR], UP, VOXEL)) == found


def _row_and_column(n_row):
    """A row of ``n_row`` points along x at 1 m (half a voxel off the cells' edges, so that they touch
    whatever the rounding), 20 points hanging below its start, and a cuboid turned 0.5 rad about up."""
    row = np.array([[1.0 + VOXEL * (i + 0.5), 1.0, 1.0] for i in range(n_row)])
    column = np.array([[1.0, 1.0, 1.0 - VOXEL * (i + 1)] for i in range(20)])
    return row, column, Cuboid([1.1, 1.0, 1.0], [0.2, 0.05, 0.05], _yaw(0.5), kind="object")


def _shelf_frame():
    """Four posts 0.6 x 0.4 m apart up to 1 m and a board on them."""
    posts = np.concatenate([_grid((x, y, ABOVE), (x, y, 1.0)) for x in (1.0, 1.6) for y in (1.0, 1.4)])
    return np.concatenate([posts, _grid((1.0, 1.0, 1.0), (1.6, 1.4, 1.0))])


@pytest.mark.parametrize("n_seed", [8, 7])
def test_a_cuboids_piece_seeds_an_object_from_8_points(n_seed):
    """A row of labelled points along x (a cuboid turned 0.5 rad) with 20 unlabelled points hanging below
    its end: from 8 points on the row seeds the object, whose box takes the cuboid's heading; with 7 the
    points are an object of their own, turned to their principal axis (x)."""
    row, column, part = _row_and_column(n_seed)
    pts, lab = _on_floor(row, column, labels=[1, -1])
    (o,) = group_objects(pts, lab, [FLOOR, part], UP, VOXEL)
    assert o.points == n_seed + 20 and o.cuboids == (1,)
    axis = o.box.rotation[:, 0]
    if n_seed == 8:
        assert abs(axis @ [math.cos(0.5), math.sin(0.5), 0.0]) == pytest.approx(1.0, abs=1e-9)
    else:
        assert abs(axis[0]) == pytest.approx(1.0, abs=1e-6)


def test_the_first_cuboid_seeds_as_well():
    """Cuboid 0 is an object (the floor comes second): its piece seeds, its heading gives the box's."""
    row, column, part = _row_and_column(8)
    pts, lab = _on_floor(row, column, labels=[0, -1])
    lab[: len(pts) - 28] = 1
    (o,) = group_objects(pts, lab, [part, FLOOR], UP, VOXEL)
    assert o.cuboids == (0,)
    assert abs(o.box.rotation[:, 0] @ [math.cos(0.5), math.sin(0.5), 0.0]) == pytest.approx(1.0, abs=1e-9)


def _top_and_vase(half_thick, tilt_deg=0.0):
    """A table top (labelled, cuboid 1) at 0.75 m with a vase of 30 unlabelled points standing on it."""
    top = _grid((1.0, 1.0, 0.75), (1.6, 1.4, 0.75))
    vase = np.array([[1.3, 1.2, 0.75 + VOXEL * (i + 1)] for i in range(30)])
    part = Cuboid([1.3, 1.2, 0.75], [0.3, 0.2, half_thick], _about_x(math.radians(tilt_deg)), kind="object")
    return _on_floor(top, vase, labels=[1, -1]), part


@pytest.mark.parametrize(
    ("half_thick", "tilt", "found"),
    [(0.05, 0.0, 2), (0.06, 0.0, 1), (0.02, 15.0, 2), (0.02, 20.5, 1), (0.02, 25.0, 1)],
)
def test_a_level_top_takes_nothing_above_it(half_thick, tilt, found):
    """A level cuboid at most 10 cm thick (tilted under 20 degrees) is a top: the vase on it is an object of
    its own; a thicker or steeper one takes the vase."""
    (pts, lab), part = _top_and_vase(half_thick, tilt)
    out = group_objects(pts, lab, [FLOOR, part], UP, VOXEL)
    assert len(out) == found
    assert out[0].cuboids == (1,)
    # the top's ceiling: its highest corner (0.75 + 0.2 sin t + h cos t) and a voxel
    t = math.radians(tilt)
    ceiling = 0.75 + 0.2 * math.sin(t) + half_thick * math.cos(t) + VOXEL
    vase_z = 0.75 + VOXEL * np.arange(1, 31)
    joined = int(np.sum(vase_z <= ceiling)) if found == 2 else 30
    assert out[0].points == 216 + joined
    if found == 2:
        assert out[1].points == 30 - joined and out[1].cuboids == ()


def test_the_top_takes_what_is_within_a_voxel_above_its_top_face():
    """The top's ceiling is its highest corner plus one voxel: a point 0.9 voxel above the cuboid's top
    joins the table, the vase above does not."""
    top = _grid((1.0, 1.0, 0.75), (1.6, 1.4, 0.75))
    part = Cuboid([1.3, 1.2, 0.74], [0.3, 0.2, 0.01], np.eye(3), kind="object")  # top face at 0.75
    bump = np.array([[1.3, 1.2, 0.75 + 0.9 * VOXEL]])
    vase = np.array([[1.3, 1.2, 0.75 + 1.9 * VOXEL + VOXEL * i] for i in range(25)])
    pts, lab = _on_floor(top, bump, vase, labels=[1, -1, -1])
    out = group_objects(pts, lab, [FLOOR, part], UP, VOXEL)
    assert sorted(o.points for o in out) == [25, len(top) + 1]


def test_growth_stops_a_metre_and_a_half_from_the_seed():
    """A rail of unlabelled points leaves a table top, one touching step (1.5 voxels) apart: 42 steps
    (int(1.5 m / 3.5 cm)) join the table, the 25 beyond are an object of their own."""
    top = _grid((0.2, 1.0, 0.75), (0.5, 1.3, 0.75), 0.9 * VOXEL)  # one touching piece however cells round
    rail = np.array([[0.5 + VOXEL * (0.25 + 1.5 * (i + 1)), 1.15, 0.75] for i in range(42 + 25)])
    part = Cuboid([0.35, 1.15, 0.74], [0.15, 0.15, 0.01], np.eye(3), kind="object")
    floor = Cuboid([3.0, 1.5, -0.02], [3.0, 1.5, 0.02], np.eye(3), kind="floor")
    pts, lab = _on_floor(top, rail, labels=[1, -1])
    out = group_objects(pts, lab, [floor, part], UP, VOXEL)
    assert [o.points for o in out] == [len(top) + 42, 25]
    assert out[0].cuboids == (1,) and out[1].cuboids == ()


def test_a_group_mostly_inside_a_larger_ones_box_joins_it():
    """A shelf's frame (a hollow box of 2 x 2 posts and two boards) and a separate stack of points inside
    it: the stack lies wholly in the frame's box and joins; one half out stays its own."""
    frame = _shelf_frame()
    inside = _grid((1.25, 1.15, 0.3), (1.35, 1.25, 0.5))
    pts, lab = _on_floor(frame, inside)
    out = group_objects(pts, lab, [FLOOR], UP, VOXEL)
    assert [o.points for o in out] == [len(frame) + len(inside)]
    half_out = _grid((1.55, 1.15, 0.3), (1.75, 1.25, 0.5))  # half its volume past the frame's x = 1.6
    pts, lab = _on_floor(frame, half_out)
    out = group_objects(pts, lab, [FLOOR], UP, VOXEL)
    assert sorted(o.points for o in out) == sorted([len(frame), len(half_out)])


def test_a_group_that_joined_another_grows_its_box_for_the_next():
    """The frame takes a block that sticks 4.5 cm out of its box (7 % of the block's); a larger block
    beside it lies 84 % inside the frame's own box, wholly inside the grown one: it joins on the next pass
    (the grown box, not the one computed before the first join, decides)."""
    frame = _shelf_frame()
    block = _grid((1.05, 1.15, 0.3), (1.66, 1.23, 0.38))  # x up to 1.645, the frame's box ends at 1.6175
    larger = _grid((1.40, 1.15, 0.6), (1.66, 1.23, 0.9))
    # compared with the frame (the largest) before the block, when it does not fit yet
    assert len(frame) > len(larger) > len(block)
    pts, lab = _on_floor(frame, block, larger)
    out = group_objects(pts, lab, [FLOOR], UP, VOXEL)
    assert [o.points for o in out] == [len(frame) + len(block) + len(larger)]
    assert _extent(out[0].box)[1][0] > 1.645  # past the frame's own box (1.6175)
    # without the block the larger one stays apart
    pts, lab = _on_floor(frame, larger)
    assert sorted(o.points for o in group_objects(pts, lab, [FLOOR], UP, VOXEL)) == sorted(
        [len(frame), len(larger)]
    )


def test_objects_come_largest_first_with_their_cuboids():
    small = _box_pts(0.3, 0.3, ABOVE, 3 * VOXEL, 3 * VOXEL, 3 * VOXEL)
    large = _box_pts(2.0, 2.0, ABOVE, 6 * VOXEL, 3 * VOXEL, 5 * VOXEL)
    pts, lab = _on_floor(small, large)
    out = group_objects(pts, lab, [FLOOR], UP, VOXEL)
    assert [o.points for o in out] == [168, 64]


@pytest.mark.parametrize(
    ("height", "kept"), [(1.0 + 0.5 * VOXEL + 0.01, False), (1.0 + 0.5 * VOXEL - 0.01, True)]
)
def test_a_sparse_patch_just_over_a_metre_up_is_left_out(height, kept):
    """A loose patch (score under 0.1) whose box bottom (half a voxel under its points) is 1 cm more or less
    than 1 m above the floor."""
    patch = _grid((1.0, 1.0, height), (1.3, 1.15, height))
    pts, lab = _on_floor(patch)
    out = group_objects(pts, lab, [FLOOR], UP, VOXEL)
    assert len(out) == int(kept)
    if kept:
        assert out[0].score < 0.1
        assert abs(out[0].box.rotation[0, 0]) == pytest.approx(
            1.0, abs=1e-6
        )  # its long side, x, in the floor


def test_a_well_filled_box_high_up_stays():
    """The high-box rule needs a low score too: a full cube of 512 points 1.5 m up, 10 cm from a wall (so
    that it does not hang clear of the walls), scores over 0.1."""
    cube = _box_pts(1.0, 1.0, 1.5, 7 * VOXEL, 7 * VOXEL, 7 * VOXEL)
    pts, lab = _on_floor(cube)
    (o,) = group_objects(pts, lab, [FLOOR, WALL_NEAR], UP, VOXEL)
    assert o.score > 0.1 and o.points == 512


def test_a_box_with_the_walls_colour_needs_20_wall_inliers():
    """A 21 cm deep bulge flat against a wall whose inliers have its colour: the wall's with 20 inliers to
    take the colour from, an object with 19."""
    wall = Cuboid([2.02, 1.5, 1.0], [0.02, 1.5, 1.0], np.eye(3), kind="wall")
    bulge = _grid((1.75, 1.0, 0.8), (1.94, 1.4, 1.2))  # 6 layers, 21 cm deep, 6 cm off the wall
    for n_wall, found in ((20, 0), (19, 1)):
        wall_pts = np.array([[2.0, 0.2 + 0.1 * i, 2.0] for i in range(n_wall)])
        pts, lab = _on_floor(bulge, wall_pts, labels=[-1, 1])
        colors = np.full((len(pts), 3), 90.0)
        colors[lab == 1] = [200.0, 200.0, 190.0]
        colors[: len(pts) - len(bulge) - n_wall] = [10.0, 10.0, 10.0]  # the floor
        colors[len(pts) - len(bulge) - n_wall : len(pts) - n_wall] = [200.0, 190.0, 200.0]
        assert len(group_objects(pts, lab, [FLOOR, wall], UP, VOXEL, colors)) == found
        assert len(group_objects(pts, lab, [FLOOR, wall], UP, VOXEL)) == 1


def test_a_scene_object_defaults_to_a_score_of_zero():
    o = SceneObject(Cuboid(np.zeros(3), np.ones(3), np.eye(3)), (), 5)
    assert o.score == 0.0 and o.to_dict(0)["score"] == 0.0
    assert o.kind == "object" and o.to_dict(0)["kind"] == "object"


# --- not_objects ------------------------------------------------------------------------------------------

WALL = Cuboid([2.0, 4.0, 1.25], [2.0, 0.02, 1.25], np.eye(3), kind="wall")  # its face at y = 3.98


def _piece(y=3.9, half=(0.1, 0.075, 0.05), x=1.0, rot=None):
    return Cuboid([x, y, 0.3], list(half), np.eye(3) if rot is None else rot, kind="object")


def test_on_wall_thickness_just_inside_and_outside():
    """gap = |centre - wall centre| - wall half - the box's full thickness; 2 x 7.5 cm = 15 cm is thin."""
    assert on_wall(_piece(), [WALL], UP) and near_wall(_piece(), [WALL], 0.15) == [0]
    assert not on_wall(_piece(half=(0.1, 0.076, 0.05)), [WALL], UP)
    assert near_wall(_piece(half=(0.1, 0.076, 0.05)), [WALL], 0.15) == []
    assert near_wall(_piece(half=(0.1, 0.2, 0.05), y=3.75), [WALL], 0.4) == [0]
    assert near_wall(_piece(half=(0.1, 0.21, 0.05), y=3.75), [WALL], 0.4) == []


@pytest.mark.parametrize(("y", "inside"), [(3.785, True), (3.775, False)])
def test_on_wall_gap_just_inside_and_outside(y, inside):
    """Centre 0.215 m from the wall's centre: gap 0.215 - 0.02 - 0.15 = 4.5 cm; 0.225 m: 5.5 cm."""
    assert on_wall(_piece(y=y), [WALL], UP) is inside
    assert (near_wall(_piece(y=y), [WALL], 0.15) == [0]) is inside


@pytest.mark.parametrize(
    ("x", "z", "on", "near"),
    [(4.19, 0.3, True, True), (4.21, 0.3, False, False), (-0.21, 0.3, False, False),
     (1.0, 2.69, True, True), (1.0, 2.71, True, False), (1.0, 4.0, True, False), (1.0, -1.0, True, False),
     (4.21, 2.71, False, False)],
)  # fmt: skip
def test_on_wall_only_over_its_width_grown_by_20_cm(x, z, on, near):
    """The wall is 4 m wide (x 0-4) and 2.5 m tall (z 0-2.5): a thin box flat on it within 20 cm of its
    width is the wall's at any height (the fit's wall stops where its support stopped); a box flat against
    it with its colour (:func:`near_wall`) must lie over its rectangle."""
    box = Cuboid([x, 3.9, z], [0.1, 0.075, 0.05], np.eye(3))
    assert on_wall(box, [WALL], UP) is on
    assert (near_wall(box, [WALL], 0.15) == [0]) is near


def test_on_wall_finds_the_walls_width_whatever_the_order_of_its_axes():
    """The same wall as :data:`WALL` with its axes listed height first (local x along up): its width is
    still along world x."""
    axes = np.array([[0.0, 1.0, 0.0], [0.0, 0.0, 1.0], [1.0, 0.0, 0.0]])  # columns: up, x, y
    wall = Cuboid(WALL.center, [1.25, 2.0, 0.02], axes, kind="wall")
    assert on_wall(_piece(), [wall], UP) and on_wall(
        Cuboid([1.0, 3.9, 4.0], [0.1, 0.075, 0.05], np.eye(3)), [wall], UP
    )
    assert not on_wall(_piece(x=4.21), [wall], UP) and on_wall(_piece(x=4.19), [wall], UP)


def test_on_wall_of_a_turned_box_and_a_turned_wall():
    """A box turned 30 degrees spans sin 30 x 0.1 + cos 30 x 0.05 = 9.3 cm each way along the wall's normal
    (18.7 cm: not thin); the same wall and box turned 90 degrees about up together are still the wall's
    when the box is thin."""
    turned = _piece(half=(0.1, 0.05, 0.05), y=3.88, rot=_yaw(math.radians(30)))
    assert not on_wall(turned, [WALL], UP) and near_wall(turned, [WALL], 0.15) == []
    assert near_wall(turned, [WALL], 0.19) == [0]
    R = _yaw(math.pi / 2)
    wall = Cuboid(R @ WALL.center, WALL.half_size, R, kind="wall")
    box = _piece()
    moved = Cuboid(R @ box.center, box.half_size, R, kind="object")
    assert on_wall(moved, [wall], UP) and near_wall(moved, [wall], 0.15) == [0]
    assert not on_wall(Cuboid(R @ [1.0, 3.7, 0.3], box.half_size, R), [wall], UP)


def test_near_wall_lists_each_wall_it_touches():
    corner = Cuboid([0.0, 2.0, 1.25], [0.02, 2.0, 1.25], np.eye(3), kind="wall")  # x = 0, face at 0.02
    box = Cuboid([0.12, 3.9, 0.3], [0.075, 0.075, 0.05], np.eye(3))
    assert near_wall(box, [WALL, corner], 0.15) == [0, 1]
    assert on_wall(box, [corner], UP) and not on_wall(box, [], UP)


def _coloured(own, wall_colour, walls=None, box=None):
    colors = np.array([own, own, [0.0, 0.0, 0.0]], dtype=float)
    return wall_coloured(box or _piece(), colors, np.array([0, 1]), walls or [WALL], wall_colour)


def test_wall_colour_within_25_just_inside_and_outside():
    wall = np.array([100.0, 100.0, 100.0])
    assert _coloured([115.0, 120.0, 100.0], {0: wall})  # 15, 20, 0: exactly 25
    assert not _coloured([115.0, 120.0, 101.0], {0: wall})
    assert not _coloured([130.0, 120.0, 100.0], {0: wall})
    assert not _coloured([100.0, 100.0, 100.0], {1: wall})  # no colour for this wall
    assert not _coloured([100.0, 100.0, 100.0], {})
    colors = np.full((3, 3), 100.0)
    assert not wall_coloured(_piece(), None, np.array([0, 1]), [WALL], {0: wall})
    assert wall_coloured(_piece(), colors, np.array([0, 1]), [WALL], {0: wall})


def test_wall_colour_of_a_box_on_no_wall_or_on_one_of_two():
    wall = np.array([100.0, 100.0, 100.0])
    away = _piece(y=2.0)
    assert not _coloured([100.0, 100.0, 100.0], {0: wall}, box=away)
    corner = Cuboid([0.0, 2.0, 1.25], [0.02, 2.0, 1.25], np.eye(3), kind="wall")
    box = Cuboid([0.12, 3.9, 0.3], [0.075, 0.075, 0.05], np.eye(3))
    both = {0: wall, 1: np.array([10.0, 10.0, 10.0])}
    assert _coloured([100.0, 100.0, 100.0], both, walls=[WALL, corner], box=box)  # matches the first
    assert _coloured([10.0, 10.0, 10.0], both, walls=[WALL, corner], box=box)  # matches the second


def test_wall_colour_takes_boxes_up_to_40_cm_thick():
    """Flat against the wall (gap 0) and 2 x 0.2 / 2 x 0.21 m thick: the colour rule's bound is 40 cm."""
    wall = np.array([100.0, 100.0, 100.0])
    thick = _piece(half=(0.1, 0.2, 0.05), y=3.78)  # its back face at 3.98, the wall's face
    thicker = _piece(half=(0.1, 0.21, 0.05), y=3.77)
    assert _coloured([100.0, 100.0, 100.0], {0: wall}, box=thick)
    assert not _coloured([100.0, 100.0, 100.0], {0: wall}, box=thicker)


def test_wall_colour_is_the_median_of_the_boxs_points():
    colors = np.array([[100.0, 100.0, 100.0], [100.0, 100.0, 100.0], [255.0, 0.0, 0.0]])
    assert wall_coloured(_piece(), colors, np.array([0, 1, 2]), [WALL], {0: np.array([100.0, 100.0, 100.0])})


def test_floor_patch_bounds():
    """Half the patch's points at most 14 cm up: 3 cm over the floor's clearance (11 cm)."""
    assert (FLOOR_PATCH_TOP_M, FLOOR_PATCH_LAYER_M, FLOOR_PATCH_MEDIAN_M) == (0.3, 0.1, 0.14)
    assert is_floor_patch(np.full(11, 0.13), 0.3)
    assert not is_floor_patch(np.full(11, 0.13), 0.31)
    assert not is_floor_patch(np.full(11, 0.15), 0.2)  # its median 15 cm up
    assert not is_floor_patch(np.linspace(0.0, 0.15, 11), 0.2)  # a layer 12 cm thick (p10 1.5, p90 13.5)


def test_floor_patch_percentiles_at_their_bounds():
    """With 11 heights the 10th, 50th and 90th percentiles are the 2nd, 6th and 10th values."""
    layer = np.array([0.12] * 9 + [0.22, 0.3])
    assert is_floor_patch(layer, 0.3)  # p90 - p10 = 0.1, p91 - p10 would be 0.108
    wide = np.array([0.02, 0.02] + [0.12] * 7 + [0.125, 0.125])
    assert not is_floor_patch(wide, 0.3)  # p90 - p10 = 0.105 (p11 would be 0.03: 0.095)
    median = np.array([0.14] * 6 + [0.24] * 5)
    assert is_floor_patch(median, 0.3)  # p50 = 0.14, p90 - p10 = 0.1; p51 would be 0.141
    assert not is_floor_patch(median + 0.001, 0.3)
    low_tail = np.array([0.11] + [0.13] * 10)
    assert is_floor_patch(low_tail, 0.15)


def _slope(degrees, n_side=4, z0=0.05, length=1.0):
    """n_side x n_side points on a plane rising ``degrees`` along x from ``z0``, their heights above a
    floor at 0."""
    x, y = np.meshgrid(np.linspace(0.0, length, n_side), np.linspace(0.0, 0.6, n_side))
    z = z0 + np.tan(np.radians(degrees)) * x
    level = np.stack([x.ravel(), y.ravel(), z.ravel()], axis=1)
    return level, level[:, 2].copy()


def test_bent_floor_bounds():
    assert is_bent_floor(*_slope(3.5))
    assert not is_bent_floor(*_slope(2.5))
    assert is_bent_floor(*_slope(14.5, length=0.4))
    assert not is_bent_floor(*_slope(15.5, length=0.4))
    ten = _slope(8.0, n_side=5)[0][:10]
    assert is_bent_floor(ten, ten[:, 2])  # ten points are enough
    assert not is_bent_floor(ten[:9], ten[:9, 2])
    level, heights = _slope(8.0)
    heights[0] = 0.35  # the highest point exactly at the bound
    assert is_bent_floor(level, heights)
    heights[0] = 0.351
    assert not is_bent_floor(level, heights)


@pytest.mark.parametrize(("rough", "bent"), [(0.0345, True), (0.0355, False)])
def test_a_bent_floor_may_be_as_rough_as_a_voxel(rough, bent):
    """A stretch of floor rising 8 degrees, its points in two layers ``rough`` above and below its plane (a
    checkerboard, so the fitted plane is the middle one and every point is ``rough`` off it): a sequence's
    fused floor is that rough up to 3.5 cm."""
    level, _ = _slope(8.0, n_side=8, z0=0.1)
    t = math.radians(8.0)
    normal = np.array([-math.sin(t), 0.0, math.cos(t)])
    sign = np.where(np.indices((8, 8)).sum(0).ravel() % 2 == 0, 1.0, -1.0)
    level = level + rough * sign[:, None] * normal
    assert is_bent_floor(level, level[:, 2]) is bent


# --- exact boundaries, with a voxel of a quarter metre (all the sums below are exact in binary) -----------

QUARTER = 0.25
SLAB = Cuboid([2.0, 2.0, -0.25], [2.0, 2.0, 0.25], np.eye(3), kind="floor")  # its top exactly at z = 0


def _column(x, z0, n, y=1.0):
    return np.array([[x, y, z0 + QUARTER * i] for i in range(n)])


def test_a_point_within_the_shell_clearance_above_the_floor_is_the_floors():
    """With a voxel of 0.25 m the clearance is 0.475 m: a column from 0.47 m loses its lowest point, one from
    0.48 m keeps all 25. The column stands half a metre past the floor cuboid's edge (x = 4), so that only
    its height over the floor's plane, not its distance from the cuboid, is at the clearance."""
    assert SHELL_CLEARANCE * QUARTER == pytest.approx(0.475)
    for z0, kept in ((0.47, 24), (0.48, 25)):
        (o,) = group_objects(_column(4.5, z0, 25), np.full(25, -1), [SLAB], UP, QUARTER)
        assert o.points == kept


def test_a_point_within_the_shell_clearance_from_a_wall_is_the_walls():
    """A wall whose face is x = 2.0 (the clearance 0.475 m at a voxel of 0.25 m): a column at x = 1.53
    (0.47 m off) belongs to it, the column beside it at x = 1.375 does not; at x = 1.52 (0.48 m off) both
    are an object."""
    wall = Cuboid([2.25, 1.0, 3.0], [0.25, 2.0, 3.0], np.eye(3), kind="wall")
    pts = np.concatenate([_column(1.53, 1.0, 21), _column(1.375, 1.0, 21)])
    (o,) = group_objects(pts, np.full(42, -1), [SLAB, wall], UP, QUARTER)
    assert o.points == 21
    lo, hi = _extent(o.box)
    assert lo[0] == pytest.approx(1.25) and hi[0] == pytest.approx(1.5)
    pts = np.concatenate([_column(1.52, 1.0, 21), _column(1.375, 1.0, 21)])
    (o,) = group_objects(pts, np.full(42, -1), [SLAB, wall], UP, QUARTER)
    assert o.points == 42


def test_a_box_exactly_three_voxels_up_does_not_stand_on_the_floor():
    """Its bottom (half a voxel under its lowest point, 0.875 m) exactly 0.75 m up: not within 3 voxels;
    from 0.75 m it is and stands on the floor."""
    for z0, bottom in ((0.875, 0.75), (0.75, 0.0)):
        (o,) = group_objects(_column(1.0, z0, 25), np.full(25, -1), [SLAB], UP, QUARTER)
        lo, _ = _extent(o.box)
        assert lo[2] == pytest.approx(bottom, abs=1e-12)


def test_a_sparse_box_exactly_a_metre_up_stays():
    """A column whose box's bottom is exactly 1 m above the floor is not "more than" a metre up, one 1.25 m
    up and as sparse is left out (score 0.7 x (1 - exp(-20/400)) x fill, under 0.1)."""
    for z0, found in ((1.125, 1), (1.375, 0)):
        out = group_objects(_column(1.0, z0, 20), np.full(20, -1), [SLAB], UP, QUARTER)
        assert len(out) == found
        if found:
            assert out[0].score < 0.1


def test_a_high_box_scoring_between_0_1_and_0_15_stays():
    """A full block of 5 x 5 x 3 points 1.5 m up: every 2-voxel cell of its views is occupied (fill 1), so
    its score is 0.7 x (1 - exp(-75 / 400)) = 0.120, over the bound of 0.1. It stands clear of the walls:
    10 cm from one, so small a block hangs on it (:func:`~cuboidcli.fitting.not_objects.hangs_on_wall`)."""
    block = _box_pts(1.0, 1.0, 1.5, 4 * VOXEL, 4 * VOXEL, 2 * VOXEL)
    assert len(block) == 75
    pts, lab = _on_floor(block)
    (o,) = group_objects(pts, lab, [FLOOR], UP, VOXEL)
    assert o.score == pytest.approx(0.7 * (1.0 - math.exp(-75 / 400)), rel=1e-9)
    assert group_objects(pts, lab, [FLOOR, WALL_NEAR], UP, VOXEL) == []


def test_object_score_of_a_single_point():
    """One point fills the one cell of a point-sized box: the score is the support, 1 - exp(-1/400)."""
    one = np.array([[1.0, 2.0, 3.0]])
    assert object_score(one, one[0], one[0], 0.05, True) == pytest.approx(1.0 - math.exp(-1 / 400), rel=1e-12)


def test_floor_reach_in_a_turned_frame():
    """The two floors of the reach test turned 0.7 rad about up (R turns level to world): the same heights."""
    R = _yaw(0.7)
    low = Cuboid(R @ [1.0, 1.0, -0.01], [1.0, 1.0, 0.01], R, kind="floor")
    high = Cuboid(R @ [3.5, 1.0, 0.29], [1.0, 1.0, 0.01], R, kind="floor")
    level = np.array([[2.21, 1.0, 1.0], [2.19, 1.0, 1.0], [2.21, 2.1, 1.0]])
    np.testing.assert_allclose(floor_heights(level, [low, high], R), [0.3, 0.0, 0.0], atol=1e-12)


def test_on_a_raised_floor_heights_are_taken_from_it():
    """A floor whose top is 0.5 m up: a flat patch 8 cm above it is the floor's, a sparse column whose box
    starts 0.875 m above it (1.375 m up) is not "high", one starting 1.125 m above it is."""
    raised = Cuboid([2.0, 2.0, 0.25], [2.0, 2.0, 0.25], np.eye(3), kind="floor")
    patch = _grid((1.0, 1.0, 0.58), (1.5, 1.4, 0.58))
    assert group_objects(patch, np.full(len(patch), -1), [raised], UP, VOXEL) == []
    for z0, found in ((1.5, 1), (1.75, 0)):
        out = group_objects(_column(1.0, z0, 20), np.full(20, -1), [raised], UP, QUARTER)
        assert len(out) == found


def test_a_merged_group_keeps_the_larger_groups_heading():
    """The stack inside the shelf's frame is a cuboid's (turned 0.5 rad); it joins the frame, the larger
    group, whose box keeps the frame's heading (its principal axis, x) and lists the cuboid."""
    frame = _shelf_frame()
    stack = _grid((1.25, 1.15, 0.3), (1.35, 1.25, 0.5), 0.9 * VOXEL)
    part = Cuboid([1.3, 1.2, 0.4], [0.05, 0.05, 0.1], _yaw(0.5), kind="object")
    pts, lab = _on_floor(frame, stack, labels=[-1, 1])
    (o,) = group_objects(pts, lab, [FLOOR, part], UP, VOXEL)
    assert o.points == len(frame) + len(stack) and o.cuboids == (1,)
    assert abs(o.box.rotation[0, 0]) == pytest.approx(1.0, abs=1e-6)  # cos 0.5 = 0.88 in its heading


def test_a_cuboid_too_small_to_seed_is_still_listed():
    """Seven points of cuboid 0 (an object) at the top of a column of free points: no seed, but the object
    they end up in lists the cuboid."""
    row, column, part = _row_and_column(7)
    pts, lab = _on_floor(row, column, labels=[0, -1])
    lab[: len(pts) - 27] = 1
    (o,) = group_objects(pts, lab, [part, FLOOR], UP, VOXEL)
    assert o.cuboids == (0,) and o.points == 27


def test_floor_height_under_a_floor_sloping_along_x_and_y():
    """A floor tilted 0.1 rad about x, then turned 0.6 rad about up: its top plane n . p = 0.01, with n the
    turned (0, -sin t, cos t), so z = (0.01 - n_x x - n_y y) / n_z."""
    rot = _yaw(0.6) @ _about_x(0.1)
    n = rot[:, 2]
    floor = Cuboid([0.0, 0.0, 0.0], [2.0, 2.0, 0.01], rot, kind="floor")
    level = np.array([[0.3, -1.0, 1.0], [-0.5, 0.7, 1.0], [1.0, 1.5, 1.0]])
    expect = (0.01 - n[0] * level[:, 0] - n[1] * level[:, 1]) / n[2]
    np.testing.assert_allclose(floor_heights(level, [floor], np.eye(3)), expect, atol=1e-12)


def test_two_groups_inside_a_larger_ones_box_both_join_it():
    frame = _shelf_frame()
    low = _grid((1.25, 1.15, 0.2), (1.35, 1.25, 0.35))
    high = _grid((1.25, 1.15, 0.6), (1.35, 1.25, 0.75))
    pts, lab = _on_floor(frame, low, high)
    out = group_objects(pts, lab, [FLOOR], UP, VOXEL)
    assert [o.points for o in out] == [len(frame) + len(low) + len(high)]


# --- boxes from the floor to the ceiling -------------------------------------------------------------------


def _column_room(top, ceiling_z):
    """A column 0.3 m square of unlabelled points from the floor to ``top`` (its sides, every voxel), and a
    ceiling cuboid whose underside is at ``ceiling_z`` (none when None)."""
    sides = [_grid((1.0, 1.0, 0.05), (1.3, 1.0, top)), _grid((1.0, 1.3, 0.05), (1.3, 1.3, top))]
    sides += [_grid((1.0, 1.0, 0.05), (1.0, 1.3, top)), _grid((1.3, 1.0, 0.05), (1.3, 1.3, top))]
    pts, lab = _on_floor(*sides)
    cuboids = [FLOOR]
    if ceiling_z is not None:
        cuboids.append(Cuboid([1.5, 1.5, ceiling_z + 0.02], [1.5, 1.5, 0.02], np.eye(3), kind="ceiling"))
    return pts, lab, cuboids


@pytest.mark.parametrize(
    ("top", "ceiling_z", "kept"),
    [
        (2.55, 2.6, False),  # a column: 98 % of the room's height
        (2.33, 2.6, False),  # the box is grown by half a voxel: 2.3475 m, 90.3 % of 2.6 m
        (2.31, 2.6, True),  # 2.3275 m, 89.5 %: a wardrobe
        (2.55, None, True),  # no ceiling
        (1.45, 1.5, True),  # a "ceiling" 1.5 m up is the top of what a sequence's views saw
        (2.55, 1.99 + 0.6, False),
    ],
)
def test_a_box_from_the_floor_to_the_ceiling_is_structure(top, ceiling_z, kept):
    pts, lab, cuboids = _column_room(top, ceiling_z)
    objects = group_objects(pts, lab, cuboids, UP, VOXEL)
    assert len(objects) == int(kept)


def test_floor_to_ceiling_bounds():
    ceiling = Cuboid([0, 0, 2.52], [2, 2, 0.02], np.eye(3), kind="ceiling")  # underside at 2.5
    low = Cuboid([0, 0, 2.06], [2, 2, 0.01], np.eye(3), kind="ceiling")  # underside at 2.05
    assert floor_to_ceiling(0.9 * 2.5, 0.0, [FLOOR, ceiling], UP)
    assert not floor_to_ceiling(0.9 * 2.5 - 1e-6, 0.0, [FLOOR, ceiling], UP)
    assert floor_to_ceiling(1.85, 0.0, [ceiling, low], UP)  # the lowest ceiling counts
    assert not floor_to_ceiling(1.9, 0.06, [low], UP)  # 1.99 m up: no room's ceiling
    seen_top = Cuboid([0, 0, 1.52], [2, 2, 0.02], np.eye(3), kind="ceiling")  # a sequence's top of view
    assert not floor_to_ceiling(1.45, 0.0, [ceiling, seen_top], UP)
    assert floor_to_ceiling(2.0, 0.3, [ceiling], UP) and not floor_to_ceiling(2.0, 0.2, [ceiling], UP)
    assert not floor_to_ceiling(3.0, 0.0, [FLOOR], UP)
    turned = Cuboid([0, 0, 2.6], [0.02, 2, 2], np.array([[0.0, 0, 1], [0, 1, 0], [-1, 0, 0]]), kind="ceiling")
    assert floor_to_ceiling(0.9 * 2.58, 0.0, [turned], UP)  # its thin axis turned to up: underside 2.58
    tilted = Cuboid([0, 0, 3.6], [2, 2, 0.02], _about_x(math.radians(30)), kind="ceiling")
    underside = 3.6 - (0.5 * 2 + math.cos(math.radians(30)) * 0.02)  # its lowest corner
    assert floor_to_ceiling(0.9 * underside + 1e-9, 0.0, [tilted], UP)
    assert not floor_to_ceiling(0.9 * underside - 1e-6, 0.0, [tilted], UP)

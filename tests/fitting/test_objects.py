"""Whole objects from a fitted room (cuboidcli.fitting.objects): legs join their top, one cuboid over two
tables gives two objects, points no cuboid explains form their own, the shell stays out."""

from __future__ import annotations

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.not_objects import on_wall
from cuboidcli.fitting.objects import floor_heights, group_objects
from cuboidcli.geometry.gravity import level_frame

UP = np.array([0.0, 0.0, 1.0])

VOXEL = 0.035


def _grid(lo, hi, step=VOXEL):
    spans = zip(lo, hi, strict=True)
    axes = [np.arange(a, b + 1e-9, step) if b - a > 1e-9 else np.array([a]) for a, b in spans]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def _table(x0, y0, w=1.0, d=0.6, h=0.75):
    top = _grid((x0, y0, h), (x0 + w, y0 + d, h))
    legs = np.concatenate(
        [
            _grid((x, y, 0.05), (x, y, h - VOXEL))
            for x in (x0 + 0.02, x0 + w - 0.02)
            for y in (y0 + 0.02, y0 + d - 0.02)
        ]
    )
    return top, legs


def _room():
    """A floor (cuboid 0), a wall (1) with a picture-less surface, two tables whose tops one cuboid (2)
    explains, and a bag (unexplained points) on the floor."""
    floor = _grid((0, 0, 0), (4, 4, 0))
    wall = _grid((0, 4, 0.1), (4, 4, 2.5))
    top_a, legs_a = _table(0.5, 0.5)
    top_b, legs_b = _table(2.5, 0.5)
    bag = _grid((1.5, 2.5, 0.06), (1.8, 2.7, 0.4))
    pts = np.concatenate([floor, wall, top_a, legs_a, top_b, legs_b, bag])
    labels = np.concatenate(
        [np.zeros(len(floor)), np.ones(len(wall)), np.full(len(top_a), 2), np.full(len(legs_a), -1),
         np.full(len(top_b), 2), np.full(len(legs_b), -1), np.full(len(bag), -1)]
    ).astype(np.int32)  # fmt: skip
    cuboids = [
        Cuboid([2, 2, -0.02], [2, 2, 0.02], np.eye(3), kind="floor"),
        Cuboid([2, 4.02, 1.3], [2, 0.02, 1.2], np.eye(3), kind="wall"),
        Cuboid([2.0, 0.8, 0.75], [1.5, 0.3, 0.005], np.eye(3), kind="object"),  # over both tables
    ]
    return pts, labels, cuboids


def _extent(box: Cuboid):
    corners = box.corners()
    return corners.min(0), corners.max(0)


def test_tables_stand_on_their_legs_and_the_bag_is_an_object():
    pts, labels, cuboids = _room()
    objects = group_objects(pts, labels, cuboids, np.array([0.0, 0.0, 1.0]), VOXEL)
    assert len(objects) == 3
    tables = sorted((o for o in objects if o.cuboids == (2,)), key=lambda o: o.box.center[0])
    assert len(tables) == 2
    for table, x0 in zip(tables, (0.5, 2.5), strict=True):
        lo, hi = _extent(table.box)
        np.testing.assert_allclose(lo, [x0 - VOXEL / 2, 0.5 - VOXEL / 2, 0.0], atol=1e-6)
        np.testing.assert_allclose(hi, [x0 + 1.0 + VOXEL / 2, 1.1 + VOXEL / 2, 0.75 + VOXEL / 2], atol=0.03)
    (bag,) = [o for o in objects if not o.cuboids]
    lo, hi = _extent(bag.box)
    assert lo[2] == 0.0 and abs(hi[2] - 0.4) < 0.03  # stands on the floor
    assert abs(lo[0] - 1.5) < 0.03 and abs(hi[1] - 2.7) < 0.03
    for o in objects:  # nothing of the wall (y = 4) or below the floor
        lo, hi = _extent(o.box)
        assert hi[1] < 3.0 and lo[2] >= 0.0


def test_any_up_direction_gives_the_same_objects():
    pts, labels, cuboids = _room()
    turn = level_frame(np.array([0.0, -1.0, 0.0]))  # z up -> -y up
    moved = [Cuboid(turn @ c.center, c.half_size, turn @ c.rotation, kind=c.kind) for c in cuboids]
    a = group_objects(pts, labels, cuboids, np.array([0.0, 0.0, 1.0]), VOXEL)
    b = group_objects(pts @ turn.T, labels, moved, turn[:, 2], VOXEL)
    assert [o.points for o in a] == [o.points for o in b]
    for oa, ob in zip(a, b, strict=True):
        np.testing.assert_allclose(turn @ oa.box.center, ob.box.center, atol=1e-6)
        np.testing.assert_allclose(np.sort(oa.box.half_size), np.sort(ob.box.half_size), atol=1e-6)


def test_small_pieces_and_empty_rooms():
    pts, labels, cuboids = _room()
    assert group_objects(pts[:0], labels[:0], cuboids, np.array([0, 0, 1.0]), VOXEL) == []
    only_shell = (labels == 0) | (labels == 1)
    assert group_objects(pts[only_shell], labels[only_shell], cuboids, np.array([0, 0, 1.0]), VOXEL) == []
    few = np.array([[1.0, 1.0, 0.5], [1.03, 1.0, 0.5]])
    assert group_objects(few, np.array([-1, -1]), cuboids, np.array([0, 0, 1.0]), VOXEL) == []


def test_two_tables_a_hand_apart_are_two_objects(monkeypatch):
    """One cuboid over two table tops 7 cm apart: its inliers are split where they do not touch closely
    (SEED_REACH), though the growth would bridge that gap (REACH)."""
    import cuboidcli.fitting.objects as objects_module

    top_a, legs_a = _table(0.5, 0.5)
    top_b, legs_b = _table(1.57, 0.5)
    pts = np.concatenate([top_a, legs_a, top_b, legs_b])
    labels = np.concatenate([np.zeros(len(top_a)), np.full(len(legs_a), -1), np.zeros(len(top_b)),
                             np.full(len(legs_b), -1)]).astype(np.int32)  # fmt: skip
    cuboids = [Cuboid([1.53, 0.8, 0.75], [1.05, 0.3, 0.005], np.eye(3))]
    up = np.array([0.0, 0.0, 1.0])
    two = group_objects(pts, labels, cuboids, up, VOXEL)
    assert len(two) == 2 and all(o.cuboids == (0,) for o in two)
    monkeypatch.setattr(objects_module, "SEED_REACH", objects_module.REACH)
    assert len(group_objects(pts, labels, cuboids, up, VOXEL)) == 1


def test_scores_rank_a_standing_table_above_a_floating_scrap():
    pts, labels, cuboids = _room()
    scrap = _grid((3.0, 3.0, 0.95), (3.3, 3.15, 0.95))  # a loose patch of points in the air
    pts = np.concatenate([pts, scrap])
    labels = np.concatenate([labels, np.full(len(scrap), -1, dtype=np.int32)])
    objects = group_objects(pts, labels, cuboids, np.array([0.0, 0.0, 1.0]), VOXEL)
    assert all(0.0 <= o.score <= 1.0 for o in objects)
    assert [o.to_dict(0)["score"] for o in objects] == [round(o.score, 4) for o in objects]
    tables = [o for o in objects if o.cuboids == (2,)]
    (floating,) = [o for o in objects if o.box.center[2] > 0.9]
    assert min(t.score for t in tables) > 3.0 * floating.score


def test_a_low_scored_box_more_than_a_metre_up_is_left_out():
    """A loose patch of points 1.2 m above the floor is a fixture's or a shelf's clutter, not furniture; the
    same patch 0.9 m up stays an object."""
    pts, labels, cuboids = _room()
    up = np.array([0.0, 0.0, 1.0])
    for height, kept in ((0.9, 4), (1.2, 3)):
        scrap = _grid((3.0, 3.0, height), (3.3, 3.15, height))
        more = np.concatenate([pts, scrap])
        more_labels = np.concatenate([labels, np.full(len(scrap), -1, dtype=np.int32)])
        assert len(group_objects(more, more_labels, cuboids, up, VOXEL)) == kept


def test_a_thin_box_against_a_wall_is_the_walls():
    wall = Cuboid([2.0, 4.0, 1.25], [2.0, 0.02, 1.25], np.eye(3), kind="wall")
    socket = Cuboid([1.0, 3.94, 0.3], [0.1, 0.04, 0.05], np.eye(3), kind="object")
    cabinet = Cuboid([1.0, 3.68, 0.4], [0.5, 0.3, 0.4], np.eye(3), kind="object")
    away = Cuboid([1.0, 2.0, 0.3], [0.1, 0.04, 0.05], np.eye(3), kind="object")
    beyond_its_end = Cuboid([5.0, 3.94, 0.3], [0.1, 0.04, 0.05], np.eye(3), kind="object")
    assert on_wall(socket, [wall], UP)
    assert not on_wall(cabinet, [wall], UP)
    assert not on_wall(away, [wall], UP)
    assert not on_wall(beyond_its_end, [wall], UP)
    # above the wall's cuboid (the fit's wall stopped at 2.5 m, the real one goes on): the wall's still
    assert on_wall(Cuboid([1.0, 3.94, 3.4], [0.1, 0.04, 0.05], np.eye(3), kind="object"), [wall], UP)


def test_each_point_stands_on_the_floor_under_it():
    """A bent scan: two floor cuboids 0.3 m apart; a point over each gets its own floor."""
    low = Cuboid([1.0, 1.0, -0.01], [1.0, 1.0, 0.01], np.eye(3), kind="floor")
    high = Cuboid([4.0, 1.0, 0.29], [1.0, 1.0, 0.01], np.eye(3), kind="floor")
    level = np.array([[1.0, 1.0, 0.5], [4.0, 1.0, 0.5], [7.0, 1.0, 0.5]])
    under = floor_heights(level, [low, high], np.eye(3))
    assert np.allclose(under, [0.0, 0.3, 0.3])


def test_a_box_against_a_wall_with_the_walls_colour_is_the_walls():
    """A 30 cm deep box flat against the wall (thicker than a socket) is the wall's when its points have
    the wall's colour, an object when they do not (a cabinet)."""
    pts, labels, cuboids = _room()
    bulge = _grid((1.0, 3.78, 0.9), (1.6, 3.95, 1.5))
    pts = np.concatenate([pts, bulge])
    labels = np.concatenate([labels, np.full(len(bulge), -1, dtype=np.int32)])
    colors = np.full((len(pts), 3), 200.0)
    up = np.array([0.0, 0.0, 1.0])
    assert len(group_objects(pts, labels, cuboids, up, VOXEL, colors)) == 3
    colors[-len(bulge) :] = [120.0, 80.0, 40.0]  # a wooden front
    assert len(group_objects(pts, labels, cuboids, up, VOXEL, colors)) == 4
    assert len(group_objects(pts, labels, cuboids, up, VOXEL)) == 4  # without colours nothing tells


def test_a_flat_patch_just_above_the_floor_is_the_floors():
    """A stretch of floor 8 cm above the floor cuboid (a real floor bends and steps) is left out; a low box
    with height in it (a footstool, 0.25 m), the lid of a box 15 cm high whose sides are hidden and a
    raised layer 0.4 m up stay objects."""
    pts, labels, cuboids = _room()
    up = np.array([0.0, 0.0, 1.0])
    base = len(group_objects(pts, labels, cuboids, up, VOXEL))

    def with_points(more):
        return group_objects(
            np.concatenate([pts, more]),
            np.concatenate([labels, np.full(len(more), -1, dtype=np.int32)]),
            cuboids,
            up,
            VOXEL,
        )

    patch = _grid((2.5, 2.5, 0.08), (3.4, 3.3, 0.08))
    assert len(with_points(patch)) == base
    seat, side = _grid((2.5, 2.5, 0.25), (2.9, 2.9, 0.25)), _grid((2.5, 2.5, 0.08), (2.5, 2.9, 0.22))
    stool = np.concatenate([seat, side])
    assert len(with_points(stool)) == base + 1
    lid = _grid((2.5, 2.5, 0.15), (3.0, 3.0, 0.15))
    assert len(with_points(lid)) == base + 1
    shelf = _grid((2.5, 2.5, 0.4), (3.4, 3.3, 0.4))
    assert len(with_points(shelf)) == base + 1


def test_a_tilted_stretch_of_floor_is_the_floors():
    """Where a scan's floor bends (a drifted reconstruction) a stretch of it rises over the floor cuboid: a
    plane 7-10 degrees from level within 0.35 m of the floor is left out. A level lid, a plane as tilted
    whose top is 0.45 m up, one tilted 20 degrees, and a tilted layer 8 cm thick stay objects."""
    pts, labels, cuboids = _room()
    up = np.array([0.0, 0.0, 1.0])
    base = len(group_objects(pts, labels, cuboids, up, VOXEL))

    def count_with(more):
        return len(
            group_objects(
                np.concatenate([pts, more]),
                np.concatenate([labels, np.full(len(more), -1, dtype=np.int32)]),
                cuboids,
                up,
                VOXEL,
            )
        )

    def sloped(z0, degrees, lo=(2.2, 2.2), hi=(3.4, 3.2)):
        plane = _grid((*lo, 0.0), (*hi, 0.0))
        plane[:, 2] = z0 + np.tan(np.radians(degrees)) * (plane[:, 0] - lo[0])
        return plane

    assert count_with(sloped(0.08, 8.0)) == base  # 0.08 -> 0.25 m
    assert count_with(sloped(0.08, 5.0)) == base
    assert count_with(sloped(0.15, 1.0)) == base + 1  # a lid lies level
    assert count_with(sloped(0.25, 8.0)) == base + 1  # up to 0.42 m: a seat's slope, not the floor
    assert count_with(sloped(0.08, 20.0, hi=(2.8, 3.2))) == base + 1  # 0.08 -> 0.30 m, too steep
    thick = np.concatenate([sloped(0.08, 8.0), sloped(0.16, 8.0)])
    assert count_with(thick) == base + 1  # two layers 8 cm apart: something with height


def test_a_table_top_without_its_legs_stands_on_the_floor():
    """A real scan often misses thin legs: a level slab floating at table height, wide enough for a table
    or a seat, and a low floating box are extended down to the floor; a shelf board 1.4 m up, a narrow
    ledge at table height, loose points at table height that no slab seeds and a tall box from 0.3 m up
    keep floating."""
    floor = _grid((0, 0, 0), (4, 4, 0))
    top, _ = _table(0.5, 0.5)  # 1.0 x 0.6 m at 0.75 m, no legs
    shelf = _grid((2.5, 0.5, 1.4), (3.5, 1.1, 1.4))
    ledge = _grid((2.0, 2.0, 0.75), (2.3, 3.0, 0.75))  # 0.3 m deep
    loose = _grid((2.5, 2.5, 0.75), (3.5, 3.1, 0.75))
    low = _grid((0.5, 3.4, 0.3), (0.8, 3.6, 0.5))  # a chair's seat and back, its legs unseen
    tall = _grid((3.4, 3.4, 0.3), (3.6, 3.6, 1.4))
    pts = np.concatenate([floor, top, shelf, ledge, loose, low, tall])
    labels = np.concatenate([np.zeros(len(floor)), np.full(len(top), 1), np.full(len(shelf), 2),
                             np.full(len(ledge), 3), np.full(len(loose) + len(low) + len(tall), -1)]
                            ).astype(np.int32)  # fmt: skip
    cuboids = [
        Cuboid([2, 2, -0.02], [2, 2, 0.02], np.eye(3), kind="floor"),
        Cuboid([1.0, 0.8, 0.75], [0.5, 0.3, 0.005], np.eye(3), kind="object"),
        Cuboid([3.0, 0.8, 1.4], [0.5, 0.3, 0.005], np.eye(3), kind="object"),
        Cuboid([2.15, 2.5, 0.75], [0.15, 0.5, 0.005], np.eye(3), kind="object"),
    ]
    objects = group_objects(pts, labels, cuboids, np.array([0.0, 0.0, 1.0]), VOXEL)
    bottoms = {o.cuboids: round(float(_extent(o.box)[0][2]), 3) for o in objects}
    assert bottoms[(1,)] == 0.0
    assert bottoms[(2,)] > 1.3 and bottoms[(3,)] > 0.7
    unseeded = {round(float(o.box.center[0]), 1): _extent(o.box) for o in objects if not o.cuboids}
    assert sorted(unseeded) == [0.6, 3.0, 3.5]
    assert unseeded[0.6][0][2] == 0.0 and abs(unseeded[0.6][1][2] - low[:, 2].max() - VOXEL / 2) < 1e-6
    assert unseeded[3.0][0][2] > 0.7 and unseeded[3.5][0][2] > 0.25
    table = next(o for o in objects if o.cuboids == (1,))
    lo, hi = _extent(table.box)  # only its bottom moves
    np.testing.assert_allclose(lo, [0.5 - VOXEL / 2, 0.5 - VOXEL / 2, 0.0], atol=1e-6)
    np.testing.assert_allclose(hi, top.max(0) + VOXEL / 2, atol=1e-6)


def test_standing_on_unseen_legs_is_measured_from_the_floor_under_the_box():
    """The same rules on a floor 0.3 m up (heights count from it): a slab whose top is 0.5 m above the floor
    stands, and so does an unseeded box from 0.2 m up; an unseeded box from 0.6 to 0.9 m above the floor
    (over the 0.45 m low bound, no slab) floats;
    a table top with a skirt down to 0.5 m and a bracket under it (two seeds, one of them a slab) stands;
    the slab cuboid first in the list (index 0) counts as a seed like any other; a ledge 0.3 m deep floats."""
    base = 0.3
    floor = _grid((0, 0, base), (4, 4, base))
    low_slab = _grid((0.5, 0.5, base + 0.5), (1.3, 1.1, base + 0.5))
    loose = _grid((2.5, 0.5, base + 0.6), (2.8, 0.8, base + 0.9))
    top = _grid((0.5, 2.5, base + 0.75), (1.5, 3.1, base + 0.75))
    skirt = np.concatenate([_grid((0.5, y, base + 0.5), (1.5, y, base + 0.72)) for y in (2.5, 3.1)])
    bracket = _grid((0.9, 2.8, base + 0.55), (1.1, 2.8, base + 0.66))
    low = _grid((3.0, 3.0, base + 0.2), (3.2, 3.2, base + 0.4))
    ledge = _grid((2.0, 3.5, base + 0.75), (3.0, 3.8, base + 0.75))  # 0.3 m deep along y
    pts = np.concatenate([floor, low_slab, loose, top, skirt, bracket, low, ledge])
    labels = np.concatenate([np.full(len(floor), 1), np.zeros(len(low_slab)), np.full(len(loose), -1),
                             np.full(len(top), 2), np.full(len(skirt), -1), np.full(len(bracket), 3),
                             np.full(len(low), -1), np.full(len(ledge), 4)]).astype(np.int32)  # fmt: skip
    cuboids = [
        Cuboid([0.9, 0.8, base + 0.5], [0.4, 0.3, 0.005], np.eye(3), kind="object"),
        Cuboid([2, 2, base - 0.02], [2, 2, 0.02], np.eye(3), kind="floor"),
        Cuboid([1.0, 2.8, base + 0.75], [0.5, 0.3, 0.005], np.eye(3), kind="object"),
        Cuboid([1.0, 2.8, base + 0.6], [0.1, 0.005, 0.06], np.eye(3), kind="object"),
        Cuboid([2.5, 3.65, base + 0.75], [0.5, 0.15, 0.005], np.eye(3), kind="object"),
    ]
    objects = group_objects(pts, labels, cuboids, np.array([0.0, 0.0, 1.0]), VOXEL)
    bottoms = {o.cuboids: round(float(_extent(o.box)[0][2]), 3) for o in objects}
    assert bottoms[(0,)] == base and bottoms[(2, 3)] == base and bottoms[(4,)] > base + 0.7
    unseeded = sorted(round(float(_extent(o.box)[0][2]), 3) for o in objects if not o.cuboids)
    assert len(unseeded) == 2 and unseeded[0] == base and unseeded[1] > base + 0.55


def test_the_groups_do_not_depend_on_where_the_points_start():
    """A bag 2.6 voxels beside a table's legs touches them (points at most REACH voxels apart). Counted in
    cells of a grid, whether they touched depended on where the grid started, and so on a stray point
    anywhere in the room; by distance the same objects come out wherever it lies."""
    from cuboidcli.fitting.objects import REACH

    floor = _grid((0, 0, 0), (3, 3, 0))
    top, legs = _table(0.5, 0.5)
    gap = 2.6 * VOXEL
    bag = _grid((1.48 + gap, 0.5, 0.1), (1.8, 1.1, 0.4))
    pts = np.concatenate([floor, top, legs, bag])
    labels = np.concatenate(
        [np.zeros(len(floor)), np.ones(len(top)), np.full(len(legs) + len(bag), -1)]
    ).astype(np.int32)
    cuboids = [
        Cuboid([1.5, 1.5, -0.02], [1.5, 1.5, 0.02], np.eye(3), kind="floor"),
        Cuboid([1.0, 0.8, 0.75], [0.5, 0.3, 0.005], np.eye(3), kind="object"),
    ]
    assert 2.6 < REACH
    found = []
    for shift in (0.0, 0.3, 0.6, 0.9):  # a stray point where the candidates' lowest corner was
        stray = np.array([[0.45 - shift * VOXEL, 0.45 - shift * VOXEL, 1.2]])
        objects = group_objects(
            np.concatenate([pts, stray]), np.concatenate([labels, [-1]]).astype(np.int32), cuboids, UP, VOXEL
        )
        found.append(sorted(tuple(np.round(_extent(o.box)[1], 3)) for o in objects))
    assert len(found[0]) == 1  # the table with its legs and the bag beside them
    assert all(f == found[0] for f in found)

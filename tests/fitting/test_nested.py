"""Nested groups (cuboidcli.fitting.nested): a group inside a larger group's box joins it when their colours
agree; a stool under a table, of another colour, stays an object of its own."""

from __future__ import annotations

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.nested import (
    MERGE_COLOUR,
    OWN_POINTS,
    UNDER_FOOTPRINT,
    UNDER_GAP_M,
    join_nested,
    join_under,
    rests_on,
)
from cuboidcli.fitting.objects import group_objects
from tests.fitting.test_objects import VOXEL, _grid

UP = np.array([0.0, 0.0, 1.0])


def _join(colours, sizes=(300, 150, 120), nested=True):
    """Group 0 (a 1 m box), group 1 inside it, group 2 inside it too when ``nested`` (else 2 m away);
    ``colours`` (one per point, or None)."""
    start = np.cumsum([0, *sizes])
    groups = {g: np.arange(start[g], start[g + 1]) for g in range(3)}
    far = (2.0, 2.0, 0.0) if not nested else (0.6, 0.6, 0.6)
    extents = {
        0: ((0, 0, 0), (1, 1, 1)),
        1: ((0.1, 0.1, 0.1), (0.5, 0.5, 0.5)),
        2: (far, tuple(np.add(far, 0.2))),
    }

    def box_of(g, h):
        lo, hi = extents[g]
        return list(lo), list(hi), float(np.prod(np.subtract(hi, lo)))

    forgotten = []
    join_nested(groups, box_of, lambda a, b: forgotten.append((a, b)), 0.9, colours)
    return groups, forgotten


def _colours(*per_group, sizes=(300, 150, 120)):
    return np.concatenate(
        [np.tile(np.asarray(c, dtype=float), (n, 1)) for c, n in zip(per_group, sizes, strict=True)]
    )


def test_a_nested_group_joins_when_the_colours_agree_or_are_unknown():
    grey = [100, 100, 100]
    for colours in (None, _colours(grey, [100, 100, 100 + MERGE_COLOUR], [0, 0, 0])):
        groups, forgotten = _join(colours, nested=False)
        assert sorted(groups) == [0, 2]  # the far group 2 never joins
        assert sorted(groups[0].tolist()) == list(range(450))
        assert forgotten == [(0, 1)]


def test_a_nested_group_of_another_colour_stays_apart():
    groups, forgotten = _join(_colours([100] * 3, [100, 100, 100.5 + MERGE_COLOUR], [0, 0, 0]))
    assert sorted(groups) == [0, 1, 2] and forgotten == []


def test_a_small_nested_group_of_another_colour_is_a_part():
    sizes = (300, OWN_POINTS - 1, 120)
    groups, _ = _join(_colours([100] * 3, [200] * 3, [0] * 3, sizes=sizes), sizes=sizes, nested=False)
    assert sorted(groups) == [0, 2]
    sizes = (300, OWN_POINTS, 120)
    groups, _ = _join(_colours([100] * 3, [200] * 3, [0] * 3, sizes=sizes), sizes=sizes, nested=False)
    assert sorted(groups) == [0, 1, 2]


def test_a_group_is_judged_by_its_colour_after_it_grew():
    """Group 0 is half grey, half red (its median between them); group 1, grey, joins it and makes it
    grey, so group 2, red, no longer has its colour (it had before group 1 joined)."""
    grey, red = [100.0, 100.0, 100.0], [170.0, 100.0, 100.0]
    half = _colours(grey, red, sizes=(150, 150))
    groups, forgotten = _join(np.concatenate([half, _colours(grey, [165.0, 100, 100], sizes=(150, 120))]))
    assert sorted(groups) == [0, 2] and forgotten == [(0, 1)]
    groups, _ = _join(np.concatenate([half, _colours([165.0, 100, 100], sizes=(270,))]))
    assert sorted(groups) == [0]  # both within 30 of the median at their turn


def _table_and_stool():
    """A table (its top explained by cuboid 1, legs by none) with a stool (cuboid 2) standing under it,
    on a floor (cuboid 0)."""
    floor = _grid((0, 0, 0), (2, 2, 0))
    top = _grid((0.5, 0.5, 0.75), (1.5, 1.1, 0.75))
    legs = np.concatenate(
        [_grid((x, y, 0.05), (x, y, 0.75 - VOXEL)) for x in (0.52, 1.48) for y in (0.52, 1.08)]
    )
    # its seat and sides, 3 cm apart so that they touch as one piece
    stool = np.unique(np.concatenate([
        _grid((0.85, 0.65, 0.45), (1.15, 0.95, 0.45), 0.03),
        *[_grid((x, 0.65, 0.09), (x, 0.95, 0.45), 0.03) for x in (0.85, 1.15)],
        *[_grid((0.85, y, 0.09), (1.15, y, 0.45), 0.03) for y in (0.65, 0.95)],
    ]), axis=0)  # fmt: skip
    pts = np.concatenate([floor, top, legs, stool])
    labels = np.concatenate(
        [np.zeros(len(floor)), np.ones(len(top)), np.full(len(legs), -1), np.full(len(stool), 2)]
    ).astype(np.int32)
    cuboids = [
        Cuboid([1, 1, -0.02], [1, 1, 0.02], np.eye(3), kind="floor"),
        Cuboid([1.0, 0.8, 0.75], [0.5, 0.3, 0.005], np.eye(3), kind="object"),
        Cuboid([1.0, 0.8, 0.265], [0.15, 0.15, 0.185], np.eye(3), kind="object"),
    ]
    colors = np.full((len(pts), 3), 150.0)
    return pts, labels, cuboids, colors, slice(len(pts) - len(stool), len(pts))


def test_a_stool_under_a_table_is_its_own_object_when_its_colour_differs():
    pts, labels, cuboids, colors, stool = _table_and_stool()
    (one,) = group_objects(pts, labels, cuboids, UP, VOXEL, colors)  # all one wood: one object
    assert one.cuboids == (1, 2)
    colors[stool] = [100.0, 150.0, 150.0]  # a stool of another wood: 50 apart in RGB
    two = group_objects(pts, labels, cuboids, UP, VOXEL, colors)
    assert sorted(o.cuboids for o in two) == [(1,), (2,)]
    (stool_box,) = [o.box for o in two if o.cuboids == (2,)]
    corners = stool_box.corners()
    np.testing.assert_allclose(corners.min(0), [0.85 - VOXEL / 2, 0.65 - VOXEL / 2, 0.0], atol=1e-6)
    np.testing.assert_allclose(
        corners.max(0), [1.15 + VOXEL / 2, 0.95 + VOXEL / 2, 0.45 + VOXEL / 2], atol=1e-6
    )
    assert len(group_objects(pts, labels, cuboids, UP, VOXEL)) == 1  # without colours nothing tells


def _under(extents):
    """join_under over groups with the given boxes ({group: (lo, hi)}), 100 points each; a joined group's
    box spans the boxes of the groups it holds."""
    groups = {g: np.arange(100 * g, 100 * (g + 1)) for g in extents}

    def box_of(g, h):
        held = sorted({int(i) // 100 for i in groups[g]})
        lo = np.min([extents[k][0] for k in held], axis=0)
        hi = np.max([extents[k][1] for k in held], axis=0)
        return lo.tolist(), hi.tolist(), float(np.prod(hi - lo))

    forgotten = []
    join_under(groups, box_of, lambda a, b: forgotten.append((a, b)))
    return groups, forgotten


SEAT = ((0.0, 0.0, 0.4), (0.6, 0.6, 0.9))  # a chair's seat and back, its base unseen


def test_a_group_touching_a_larger_box_from_below_joins_it():
    for top in (0.305, 0.35, 0.4, 0.495):  # within UNDER_GAP_M of the seat's bottom, below or above it
        groups, forgotten = _under({0: SEAT, 1: ((0.2, 0.2, 0.0), (0.4, 0.4, top))})
        assert list(groups) == [0] and forgotten == [(0, 1)], top
        assert sorted(groups[0].tolist()) == list(range(200))
    for top in (0.295, 0.505):
        groups, forgotten = _under({0: SEAT, 1: ((0.2, 0.2, 0.0), (0.4, 0.4, top))})
        assert sorted(groups) == [0, 1] and forgotten == [], top


def test_a_group_joins_from_below_only_under_half_the_larger_footprint():
    assert UNDER_GAP_M == 0.1 and UNDER_FOOTPRINT == 0.5
    for x0, joins in ((0.45, True), (0.495, True), (0.505, False), (0.7, False)):  # 0.2 wide, x up to 0.6
        groups, _ = _under({0: SEAT, 1: ((x0, 0.2, 0.0), (x0 + 0.2, 0.4, 0.38))})
        assert (sorted(groups) == [0]) is joins, x0


def test_what_stands_on_or_beside_a_box_stays_its_own():
    cases = [
        ((0.2, 0.2, 0.4), (0.4, 0.4, 0.45)),  # its bottom no lower than the larger box's
        ((0.2, 0.2, 0.9), (0.4, 0.4, 1.2)),  # on top
        ((0.2, 0.2, 0.0), (0.4, 0.4, 0.8)),  # beside it, as tall
    ]
    for box in cases:
        groups, _ = _under({0: SEAT, 1: box})
        assert sorted(groups) == [0, 1], box
    # a larger box below a smaller one: the small one lies on it, the larger one holds it up
    groups, _ = _under({0: ((0.2, 0.2, 0.4), (0.4, 0.4, 0.6)), 1: ((0.0, 0.0, 0.0), (0.6, 0.6, 0.38))})
    assert sorted(groups) == [0, 1]


def _rests(box, below):
    """rests_on for group 0 with ``box`` over group 1 with ``below`` (each (lo, hi))."""
    extents = {0: box, 1: below}
    groups = {0: np.arange(10), 1: np.arange(10, 20)}

    def box_of(g, h):
        lo, hi = (np.asarray(v, dtype=float) for v in extents[g])
        return lo.tolist(), hi.tolist(), float(np.prod(hi - lo))

    return rests_on(0, groups, box_of)


DESK = ((0.0, 0.0, 0.0), (1.2, 0.6, 0.75))


def test_a_box_rests_on_a_box_under_it():
    for bottom in (0.655, 0.75, 0.845):  # within UNDER_GAP_M of the desk's top, above or below it
        assert _rests(((0.4, 0.1, bottom), (0.8, 0.3, bottom + 0.5)), DESK), bottom
    for bottom in (0.645, 0.855):
        assert not _rests(((0.4, 0.1, bottom), (0.8, 0.3, bottom + 0.5)), DESK), bottom
    # at least half its footprint over the desk: 0.4 wide, the desk's edge at x = 1.2
    assert _rests(((0.995, 0.1, 0.75), (1.395, 0.3, 1.25)), DESK)
    assert not _rests(((1.005, 0.1, 0.75), (1.405, 0.3, 1.25)), DESK)
    assert not _rests(((0.4, 0.1, 1.0), (0.8, 0.3, 1.5)), DESK)  # above it, on nothing
    groups = {0: np.arange(10)}  # alone
    assert not rests_on(0, groups, lambda g, h: ([0.0, 0.0, 0.75], [1.0, 1.0, 1.0], 0.25))


def test_pieces_under_pieces_join_in_turn():
    groups, forgotten = _under(
        {0: SEAT, 1: ((0.1, 0.1, 0.2), (0.5, 0.5, 0.38)), 2: ((0.2, 0.2, 0.0), (0.4, 0.4, 0.25))}
    )
    assert list(groups) == [0] and len(groups[0]) == 300 and forgotten == [(0, 1), (0, 2)]


def _chair():
    """A floor (cuboid 0), a chair's seat and back (cuboid 1) and its pedestal, seeded by a cuboid of its own
    (2), 5 cm under the seat."""
    floor = _grid((-0.5, -0.5, 0), (1.0, 1.0, 0))
    seat = _grid((0.0, 0.0, 0.45), (0.5, 0.5, 0.45))
    back = _grid((0.0, 0.5, 0.45 + VOXEL), (0.5, 0.5, 0.9))
    pedestal = _grid((0.22, 0.22, 0.06), (0.28, 0.28, 0.4))
    pts = np.concatenate([floor, seat, back, pedestal])
    labels = np.concatenate(
        [np.zeros(len(floor)), np.ones(len(seat) + len(back)), np.full(len(pedestal), 2)]
    ).astype(np.int32)
    cuboids = [
        Cuboid([0.25, 0.25, -0.02], [0.75, 0.75, 0.02], np.eye(3), kind="floor"),
        Cuboid([0.25, 0.25, 0.675], [0.25, 0.25, 0.225], np.eye(3), kind="object"),
        Cuboid([0.25, 0.25, 0.23], [0.03, 0.03, 0.17], np.eye(3), kind="object"),
    ]
    return pts, labels, cuboids


def test_a_chair_and_its_pedestal_are_one_object():
    pts, labels, cuboids = _chair()
    (chair,) = group_objects(pts, labels, cuboids, UP, VOXEL)
    assert chair.cuboids == (1, 2)
    corners = chair.box.corners()
    np.testing.assert_allclose(corners.min(0), [-VOXEL / 2, -VOXEL / 2, 0.0], atol=1e-6)  # on the floor
    top = pts[labels == 1].max(0) + VOXEL / 2  # the back's corner, 0.49 / 0.5 / 0.87 m
    np.testing.assert_allclose(corners.max(0), top, atol=1e-6)


def test_a_scrap_of_wall_under_a_box_joins_nothing():
    """A wall cupboard (cuboid 2) with a strip of the wall under it, flat against the wall (cuboid 3's): the
    strip is the wall's, left out before anything joins, so the cupboard keeps its own box."""
    floor = _grid((0.0, 2.0, 0.0), (3.0, 4.0, 0.0))
    wall = _grid((0.0, 4.0, 0.1), (3.0, 4.0, 2.4))
    cupboard = np.unique(np.concatenate([
        _grid((1.0, 3.55, 1.0), (1.6, 3.95, 1.0)), _grid((1.0, 3.55, 1.3), (1.6, 3.95, 1.3)),
        _grid((1.0, 3.55, 1.0), (1.6, 3.55, 1.3)),
    ]), axis=0)  # fmt: skip
    strip = _grid((1.1, 3.935, 0.5), (1.5, 3.935, 0.95))
    pts = np.concatenate([floor, wall, cupboard, strip])
    labels = np.concatenate(
        [np.zeros(len(floor)), np.ones(len(wall)), np.full(len(cupboard), 2), np.full(len(strip), 3)]
    ).astype(np.int32)
    cuboids = [
        Cuboid([1.5, 3.0, -0.02], [1.5, 1.0, 0.02], np.eye(3), kind="floor"),
        Cuboid([1.5, 4.02, 1.25], [1.5, 0.02, 1.15], np.eye(3), kind="wall"),
        Cuboid([1.3, 3.75, 1.15], [0.3, 0.2, 0.15], np.eye(3), kind="object"),
        Cuboid([1.3, 3.935, 0.725], [0.2, 0.005, 0.225], np.eye(3), kind="object"),
    ]
    (cupboard_box,) = [o.box for o in group_objects(pts, labels, cuboids, UP, VOXEL)]
    corners = cupboard_box.corners()
    np.testing.assert_allclose(corners.min(0)[2], 1.0 - VOXEL / 2, atol=1e-6)
    np.testing.assert_allclose(corners.max(0)[2], 1.3 + VOXEL / 2, atol=1e-6)

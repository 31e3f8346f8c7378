"""Nested groups (cuboidcli.fitting.nested): a group inside a larger group's box joins it when their colours
agree; a stool under a table, of another colour, stays an object of its own."""

from __future__ import annotations

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.nested import MERGE_COLOUR, OWN_POINTS, join_nested
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

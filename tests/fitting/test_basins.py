"""Sinks set into a counter (cuboidcli.fitting.basins): the dent in a level top at counter height gets a box
of its own; a seat between armrests, a laptop on a desk, a gap between two tables, a low table's dent and
dents too shallow, deep, small or large do not."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.basins import ABOVE_M, DEPTH_M, SIZE_M, TOP_M, find_basins, object_basins
from cuboidcli.fitting.objects import group_objects

VOXEL = 0.035


def _sheet(x0, x1, y0, y1, z, step=VOXEL):
    x, y = np.meshgrid(np.arange(x0, x1 + 1e-9, step), np.arange(y0, y1 + 1e-9, step), indexing="ij")
    return np.stack([x.ravel(), y.ravel(), np.full(x.size, z)], 1)


def _counter(top=0.9, sink=((0.7, 1.1), (0.1, 0.5)), depth=0.18, size=(1.8, 0.6), bottom=False):
    """A counter's top (x 0..size[0], y 0..size[1]) at ``top`` with a bowl cut into it: the bowl's four walls
    falling from a third of ``depth`` below the rim to ``depth``, and its bottom only when ``bottom``;
    points (N, 3), z up from the floor at 0, none outside the counter's footprint."""
    pts = _sheet(0, size[0], 0, size[1], top)
    if sink is None:
        return pts
    (x0, x1), (y0, y1) = sink
    pts = pts[~((pts[:, 0] > x0) & (pts[:, 0] < x1) & (pts[:, 1] > y0) & (pts[:, 1] < y1))]
    walls = []
    for k, t in enumerate(np.linspace(0.35, 1.0, 5)):  # rings shrinking 3 cm a step, going down
        inset, z = 0.03 * (k + 1), top - depth * t
        ring = _sheet(x0 + inset, x1 - inset, y0 + inset, y1 - inset, z)
        edge = (
            (ring[:, 0] < x0 + inset + VOXEL)
            | (ring[:, 0] > x1 - inset - VOXEL)
            | (ring[:, 1] < y0 + inset + VOXEL)
            | (ring[:, 1] > y1 - inset - VOXEL)
        )
        walls.append(ring[edge])
    if bottom:
        walls.append(_sheet(x0 + 0.15, x1 - 0.15, y0 + 0.15, y1 - 0.15, top - depth))
    pts = np.concatenate([pts, *walls])
    inside = (pts[:, 0] >= 0) & (pts[:, 0] <= size[0]) & (pts[:, 1] >= 0) & (pts[:, 1] <= size[1])
    return pts[inside]


def _basins(pts, own=None):
    own = pts if own is None else own
    return find_basins(pts, pts[:, 2], own[:, 2], VOXEL)


@pytest.mark.parametrize("bottom", [False, True])
@pytest.mark.parametrize("offset", [(0.0, 0.0), (2.0, -1.0)])
def test_a_sink_in_a_counter_gets_its_box(bottom, offset):
    shift = np.array([*offset, 0.0])
    pts = _counter(bottom=bottom) + shift
    (basin,) = _basins(pts)
    lo, hi, inside = basin[0] - shift, basin[1] - shift, basin[2]
    # the bowl's opening spans x 0.7-1.1, y 0.1-0.5: the patch of whole cells inside the rim, grown by half a
    # cell, is within a cell of it
    cell = 2 * VOXEL
    np.testing.assert_allclose(lo[:2], [0.7, 0.1], atol=cell)
    np.testing.assert_allclose(hi[:2], [1.1, 0.5], atol=cell)
    np.testing.assert_allclose((hi - lo)[:2] / cell, np.round((hi - lo)[:2] / cell), atol=1e-9)
    # from the bowl's lowest point 0.18 m down to the top, each with half a voxel
    np.testing.assert_allclose([lo[2], hi[2]], [0.9 - 0.18 - VOXEL / 2, 0.9 + VOXEL / 2], atol=1e-9)
    assert inside.sum() >= 10 and np.all(pts[inside, 2] < 0.9 - DEPTH_M[0])


@pytest.mark.parametrize(("width", "found"), [(0.22, False), (0.25, True), (0.85, True), (0.95, False)])
def test_a_sinks_width(width, found):
    assert len(_basins(_counter(sink=((0.5, 0.5 + width), (0.1, 0.5))))) == int(found)


@pytest.mark.parametrize(("depth", "found"), [(0.06, False), (0.08, True), (0.25, True), (0.3, False)])
def test_a_sinks_depth(depth, found):
    assert len(_basins(_counter(depth=depth))) == int(found)


def test_a_tap_and_the_cupboard_over_the_sink_do_not_hide_it():
    pts = _counter()
    tap = _sheet(0.88, 0.92, 0.52, 0.56, 1.05)
    cupboard = _sheet(0.0, 1.8, 0.0, 0.6, 0.9 + ABOVE_M + 0.1)  # above the reach: not looked at
    (basin,) = _basins(np.concatenate([pts, tap, cupboard]))
    np.testing.assert_allclose(basin[0][:2], [0.7, 0.1], atol=2 * VOXEL)


def test_what_stands_on_the_rim_closes_it_in():
    """Bottles along the whole back of the rim hide its top there: they stand on it and close it in."""
    pts = _counter()
    rim = (
        (pts[:, 2] >= 0.9 - 1e-9)
        & (pts[:, 1] > 0.5)
        & (pts[:, 1] < 0.6)
        & (pts[:, 0] > 0.6)
        & (pts[:, 0] < 1.2)
    )
    bottles = pts[rim] + [0.0, 0.0, 0.2]
    (basin,) = _basins(np.concatenate([pts[~rim], bottles]))
    np.testing.assert_allclose(basin[1][1], 0.5, atol=2 * VOXEL)


@pytest.mark.parametrize(("top", "found"), [(0.7, True), (0.95, True), (1.4, False), (0.5, False)])
def test_a_vanity_and_a_kitchen_counter_but_not_a_shelf_or_a_seat(top, found):
    assert len(_basins(_counter(top=top))) == int(found)


def test_a_drains_few_deeper_points_keep_the_sink():
    pts = _counter()
    drain = np.array([[0.9, 0.3, 0.9 - 2 * DEPTH_M[1]]]) + np.array([[0, 0, 0], [0.02, 0, 0], [0, 0.02, 0]])
    (basin,) = _basins(np.concatenate([pts, drain]))
    assert basin[0][2] > 0.9 - DEPTH_M[1]  # the box ends at the bowl's lowest point within reach


def test_points_beyond_the_objects_footprint_do_not_close_its_dent():
    """object_basins looks at the points over the object's box only: a chair's seat at counter height just
    in front of a dent open at the counter's front edge does not close it."""
    counter = _counter(sink=((0.7, 1.1), (-0.1, 0.4)))
    seat = _sheet(0.5, 1.3, -0.3, -0.02, 0.9)
    level = np.concatenate([counter, seat])
    members = np.arange(len(counter))
    lo, hi = np.array([0.0, 0.0, 0.0]), np.array([1.8, 0.6, 0.9])
    assert object_basins(level, level[:, 2], members, np.eye(3), lo, hi, VOXEL) == []
    assert len(find_basins(level, level[:, 2], level[:, 2], VOXEL)) == 1  # over everything, it is closed


def test_the_bowls_points_may_belong_to_another_group():
    pts = _counter()
    rim = pts[pts[:, 2] >= 0.9 - 1e-9]
    (basin,) = _basins(pts, own=rim)
    assert basin[2].sum() >= 10


@pytest.mark.parametrize(
    "case",
    [
        "armchair",
        "laptop",
        "gap to the floor",
        "low table",
        "shallow",
        "deep",
        "small",
        "large",
        "at the edge",
    ],
)
def test_what_is_no_sink(case):
    if case == "armchair":  # a seat 0.2 m below its arms, open at the front
        arms = np.concatenate([_sheet(0, 0.15, 0, 0.8, 0.65), _sheet(0.75, 0.9, 0, 0.8, 0.65)])
        back = _sheet(0, 0.9, 0.65, 0.8, 0.65)
        seat = _sheet(0.18, 0.72, 0.0, 0.62, 0.45)
        pts = np.concatenate([arms, back, seat])
    elif case == "laptop":  # something on a desk rises above its top
        desk = _sheet(0, 1.4, 0, 0.7, 0.75)
        pts = np.concatenate([desk, _sheet(0.5, 0.85, 0.2, 0.45, 0.77)])
        pts = pts[
            ~(
                (pts[:, 2] < 0.76)
                & (pts[:, 0] > 0.5)
                & (pts[:, 0] < 0.85)
                & (pts[:, 1] > 0.2)
                & (pts[:, 1] < 0.45)
            )
        ]
    elif case == "gap to the floor":  # the floor seen between tables, their rails 15 cm under the tops
        pts = _counter(sink=((0.7, 1.1), (0.1, 0.5)), depth=0.15)
        pts = np.concatenate([pts, _sheet(0.7, 1.1, 0.1, 0.5, 0.0)])
    elif case == "low table":  # a coffee table's dent lies below counter height
        pts = _counter(top=TOP_M[0] - 0.15)
    elif case == "shallow":
        pts = _counter(depth=0.04)
    elif case == "deep":  # a tub or a bin: the walls reach twice the deepest sink's depth
        pts = _counter(depth=2 * DEPTH_M[1])
    elif case == "small":
        pts = _counter(sink=((0.8, 0.8 + SIZE_M[0] - 0.08), (0.2, 0.3)))
    elif case == "large":
        pts = _counter(sink=((0.2, 1.6), (0.05, 0.55)), size=(1.8, 0.6))
    else:  # a dent that reaches the counter's edge is not closed in
        pts = _counter(sink=((0.7, 1.1), (-0.1, 0.4)))
    assert _basins(pts) == []


@pytest.mark.parametrize(
    "sink",
    [
        ((-0.1, 0.3), (0.1, 0.5)),
        ((1.5, 1.9), (0.1, 0.5)),
        ((0.7, 1.1), (-0.1, 0.3)),
        ((0.7, 1.1), (0.3, 0.7)),
    ],
)
def test_a_dent_open_at_any_edge_is_no_sink(sink):
    assert _basins(_counter(sink=sink)) == []


def test_a_counter_with_a_sink_gives_a_second_object():
    """group_objects: the counter (one cuboid, its top and front) and, inside its box, the sink's box."""
    floor = _sheet(-0.5, 2.5, -0.5, 1.5, 0.0)
    top = _counter()
    front = np.stack(
        np.meshgrid(np.arange(0, 1.8, VOXEL), [0.0], np.arange(0.1, 0.88, VOXEL), indexing="ij"), -1
    )
    front = front.reshape(-1, 3)
    pts = np.concatenate([floor, top, front])
    is_top = np.arange(len(pts)) >= len(floor)
    labels = np.where(is_top, 1, 0).astype(np.int32)
    labels[len(floor) : len(floor) + len(top)][top[:, 2] < 0.9 - 1e-9] = -2  # inside the counter's cuboid
    cuboids = [
        Cuboid([1.0, 0.5, -0.02], [1.5, 1.0, 0.02], np.eye(3), kind="floor"),
        Cuboid([0.9, 0.3, 0.45], [0.9, 0.3, 0.45], np.eye(3), kind="object"),
    ]
    objects = group_objects(pts, labels, cuboids, np.array([0.0, 0.0, 1.0]), VOXEL)
    assert len(objects) == 2
    counter, sink = sorted(objects, key=lambda o: -o.points)
    assert counter.cuboids == (1,) and sink.cuboids == ()
    assert (counter.kind, sink.kind) == ("object", "sink")
    assert sink.to_dict(1)["kind"] == "sink"
    corners = sink.box.corners()
    np.testing.assert_allclose(corners.min(0), [0.7, 0.1, 0.72], atol=2 * VOXEL)
    np.testing.assert_allclose(corners.max(0), [1.1, 0.5, 0.9], atol=2 * VOXEL)
    assert 0.0 < sink.score < counter.score

"""Boxes high in a room that are not furniture (:func:`cuboidcli.fitting.not_objects.high_up`): low-scored
ones more than a metre up, and ones no cuboid explains above a door's top (a rail, a light, a moulding)."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.not_objects import DOOR_TOP_M, HIGH_M, HIGH_SCORE, high_up
from cuboidcli.fitting.objects import group_objects
from tests.fitting.test_objects import VOXEL, _grid

UP = np.array([0.0, 0.0, 1.0])
FLOOR = Cuboid([2.0, 2.0, -0.02], [2.0, 2.0, 0.02], np.eye(3), kind="floor")  # top face at z = 0
#: A wall along y whose face is at x = 0 (the room is x > 0).
WALL = Cuboid([-0.05, 2.0, 1.3], [0.05, 2.0, 1.3], np.eye(3), kind="wall")


def _room(*parts, labels=None, cuboids=()):
    """Floor points (cuboid 0, every other voxel) and the parts, unlabelled unless ``labels`` gives one
    label per part; the cuboids are the floor, the wall and ``cuboids``."""
    floor = _grid((0.1, 0.1, 0.0), (3.9, 3.9, 0.0), 2 * VOXEL)
    labels = labels or [-1] * len(parts)
    pts = np.concatenate([floor, *parts])
    lab = np.concatenate(
        [np.zeros(len(floor))] + [np.full(len(p), k) for p, k in zip(parts, labels, strict=True)]
    )
    return pts, lab.astype(np.int32), [FLOOR, WALL, *cuboids]


def test_high_up_bounds():
    assert (HIGH_M, HIGH_SCORE, DOOR_TOP_M) == (1.0, 0.1, 2.0)
    # a low score more than a metre up, seeded or not
    assert high_up(1.0 + 1e-6, 0.099, True) and high_up(1.0 + 1e-6, 0.099, False)
    assert not high_up(1.0, 0.099, True) and not high_up(1.5, 0.1, True)
    # no cuboid and above a door's top, whatever the score
    assert high_up(2.0, 0.9, False) and not high_up(2.0 - 1e-6, 0.9, False)
    assert not high_up(2.4, 0.9, True)  # a cuboid holds it: a cupboard over a refrigerator
    assert not high_up(-0.5, 0.0, False)  # on the floor


def _rail(z):
    """A rail 1.2 m long along the wall, 10 cm from it: 7 x 35 x 4 points from height ``z``."""
    return _grid((0.1, 1.0, z), (0.31, 2.19, z + 0.105))


@pytest.mark.parametrize(
    ("z", "seeded", "kept"),
    [
        (2.3, False, False),  # above the doors, no cuboid: a curtain rail
        (2.0 + 0.5 * VOXEL, False, False),  # its box's bottom (half a voxel under its points) at 2 m
        (2.0 + 0.5 * VOXEL - 0.01, False, True),  # 1 cm lower
        (1.9, False, True),  # below a door's top
        (2.3, True, True),  # a cuboid explains it: a shelf
    ],
)
def test_a_rail_above_the_doors_that_no_cuboid_explains_is_left_out(z, seeded, kept):
    rail = _rail(z)
    shelf = Cuboid([0.2, 1.6, z + 0.05], [0.1, 0.6, 0.05], np.eye(3), kind="object")
    pts, lab, cuboids = _room(rail, labels=[2 if seeded else -1], cuboids=(shelf,) if seeded else ())
    out = group_objects(pts, lab, cuboids, UP, VOXEL)
    assert len(out) == int(kept)
    if kept:
        assert out[0].points == len(rail) and out[0].score > HIGH_SCORE
        assert out[0].cuboids == ((2,) if seeded else ())

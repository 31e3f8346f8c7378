"""A door-sized box against a wall is a door even with the wall's colour
(:func:`cuboidcli.fitting.not_objects.door_panel`, in :func:`cuboidcli.fitting.objects.group_objects`)."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.not_objects import DOOR_FLOOR_M, DOOR_PANEL_HEIGHT_M, DOOR_PANEL_WIDTH_M, door_panel
from cuboidcli.fitting.objects import group_objects

VOXEL = 0.035
UP = np.array([0.0, 0.0, 1.0])
FLOOR = Cuboid([1.5, 1.5, -0.02], [1.5, 1.5, 0.02], np.eye(3), kind="floor")  # top face at z = 0
WALL = Cuboid([2.02, 1.5, 1.25], [0.02, 1.5, 1.25], np.eye(3), kind="wall")  # its face at x = 2.0
WALL_COLOUR = [200.0, 200.0, 190.0]


def test_door_panel_bounds():
    assert (DOOR_FLOOR_M, DOOR_PANEL_HEIGHT_M, DOOR_PANEL_WIDTH_M) == (0.1, 1.2, (0.6, 1.2))
    assert door_panel(0.8, 2.0, 0.0) and door_panel(0.6, 1.2, 0.1) and door_panel(1.2, 1.2, 0.0)
    assert not door_panel(0.59, 2.0, 0.0) and not door_panel(1.21, 2.0, 0.0)
    assert not door_panel(0.8, 1.19, 0.0) and not door_panel(0.8, 2.0, 0.11)


def _grid(lo, hi):
    axes = [np.arange(a, b + 1e-9, VOXEL) for a, b in zip(lo, hi, strict=True)]
    return np.stack(np.meshgrid(*axes, indexing="ij"), -1).reshape(-1, 3)


def _room(panel: np.ndarray, panel_colour, dz: float = 0.0, dxy=(0.0, 0.0)) -> list:
    """The objects of a floor, a wall at x = 2 with 30 inliers of its colour, and ``panel`` (points off the
    wall by more than the shell's clearance) of ``panel_colour``; all of it ``dz`` higher and moved by ``dxy``
    across the floor."""
    floor = _grid((0.0, 0.0, 0.0), (3.0, 3.0, 0.0))[::2]
    wall = np.array([[2.0, 0.1 + 0.09 * i, 2.2] for i in range(30)])
    shift = np.array([*dxy, dz])
    pts = np.concatenate([floor, wall, panel]) + shift
    lab = np.concatenate([np.zeros(len(floor)), np.ones(len(wall)), np.full(len(panel), -1)]).astype(np.int32)
    colors = np.full((len(pts), 3), 20.0)
    colors[lab == 1] = WALL_COLOUR
    colors[lab == -1] = panel_colour
    up = [Cuboid(c.center + shift, c.half_size, c.rotation, kind=c.kind) for c in (FLOOR, WALL)]
    return group_objects(pts, lab, up, UP, VOXEL, colors)


@pytest.mark.parametrize(
    ("y_hi", "z_lo", "z_hi", "door"),
    [
        (1.8, 0.14, 1.4, True),  # 0.805 m wide, 1.42 m tall, on the floor
        (1.8, 0.14, 1.0, False),  # 1.02 m tall: a bulge of the wall
        (1.5, 0.14, 1.4, False),  # 0.525 m wide
        (2.4, 0.14, 1.4, False),  # 1.435 m wide
        (1.8, 0.30, 1.7, False),  # 0.28 m above the floor
    ],
)
def test_a_wall_coloured_box_is_kept_when_it_has_a_doors_size(y_hi, z_lo, z_hi, door):
    """A 17.5 cm deep panel flat against the wall with the wall's colour is the wall's unless it stands on
    the floor at a door's size; with a colour of its own it is an object at any size."""
    panel = _grid((1.78, 1.0, z_lo), (1.92, y_hi, z_hi))
    objects = _room(panel, WALL_COLOUR)
    assert len(objects) == int(door)
    if door:
        (o,) = objects
        assert o.points == len(panel)
        lo, hi = o.box.corners().min(0), o.box.corners().max(0)
        np.testing.assert_allclose(lo, [*(panel.min(0)[:2] - VOXEL / 2), 0.0], atol=1e-6)  # down to the floor
        np.testing.assert_allclose(hi, panel.max(0) + VOXEL / 2, atol=1e-6)
    assert len(_room(panel, [120.0, 80.0, 40.0])) == 1  # a wooden front
    assert len(_room(panel, WALL_COLOUR, dz=1.0)) == int(door)  # the same room 1 m higher
    for dxy in ((5.0, -4.0), (-5.0, 4.0)):  # and elsewhere on the floor
        assert len(_room(panel, WALL_COLOUR, dxy=dxy)) == int(door), dxy

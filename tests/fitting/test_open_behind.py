"""A long, thin upright object slab with nothing behind it is a stretch of wall
(:func:`cuboidcli.fitting.room.open_behind_is_wall`): what stands in the room has the room behind it, what
stands against a wall has the wall behind it above its top."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.room import OPEN_BEHIND_M, OPEN_BEHIND_SHARE, OPEN_SLABS, open_behind_is_wall

UP = np.array([0.0, 0.0, 1.0])
INSIDE = np.array([2.0, 1.5, 1.2])


def slab(x=4.0, length=2.0, thick=0.04, z=(0.5, 1.1), kind="object", rotation=np.eye(3)):
    """An upright slab across x (its normal), ``length`` along y, from ``z[0]`` to ``z[1]``."""
    return Cuboid(
        [x, 1.5, (z[0] + z[1]) / 2], [thick / 2, length / 2, (z[1] - z[0]) / 2], rotation, kind=kind
    )


def own_points(c: Cuboid, n: int = 200, seed: int = 0) -> np.ndarray:
    """``n`` points inside the cuboid ``c``."""
    local = np.random.default_rng(seed).uniform(-1.0, 1.0, (n, 3)) * c.half_size * 0.999
    return local @ c.rotation.T + c.center


def room(n: int = 3000, seed: int = 1) -> np.ndarray:
    """A room's floor (z = 0) and its walls at x = 0 and y = 0 / 3, 2.5 m high; nothing beyond x = 3.9."""
    rng = np.random.default_rng(seed)
    floor = np.c_[rng.uniform(0, 3.9, (n, 1)), rng.uniform(0, 3, (n, 1)), np.zeros((n, 1))]
    back = np.c_[np.zeros((n, 1)), rng.uniform(0, 3, (n, 1)), rng.uniform(0, 2.5, (n, 1))]
    sides = np.c_[rng.uniform(0, 3.9, (n, 1)), rng.choice([0.0, 3.0], (n, 1)), rng.uniform(0, 2.5, (n, 1))]
    return np.concatenate([floor, back, sides])


def kind_after(c: Cuboid, points: np.ndarray, viewpoint=INSIDE) -> str:
    open_behind_is_wall([c], points, UP, viewpoint)
    return c.kind


def test_a_strip_of_wall_with_nothing_behind_it_is_a_wall():
    strip = slab()
    assert kind_after(strip, np.concatenate([room(), own_points(strip)])) == "wall"


def test_what_stands_in_the_room_or_against_a_wall_stays_an_object():
    walls = room()
    back = slab(x=2.5, z=(0.0, 0.9))  # a sofa's back in the room: the far wall is not behind it, but the
    # floor from x = 2.6 on is
    assert kind_after(back, np.concatenate([walls, own_points(back)])) == "object"
    wall = np.c_[np.full(3000, 4.0), np.random.default_rng(2).uniform(0, 3, 3000), np.linspace(0, 2.5, 3000)]
    front = slab(x=3.7, z=(0.0, 0.9))  # a cabinet's front 30 cm before a wall that the scan saw above it
    above = wall[wall[:, 2] > 0.9]
    assert kind_after(front, np.concatenate([above, own_points(front)])) == "object"


@pytest.mark.parametrize(("extra", "kind"), [(10, "wall"), (11, "object")])
def test_a_few_points_behind_are_allowed_up_to_a_share_of_its_own(extra, kind):
    strip = slab()
    behind = np.c_[np.full(extra, 4.5), np.linspace(0.6, 2.4, extra), np.full(extra, 2.0)]  # 48 cm behind
    assert OPEN_BEHIND_SHARE * 200 == 10
    assert kind_after(strip, np.concatenate([own_points(strip), behind])) == kind


@pytest.mark.parametrize(
    ("depth", "kind"), [(0.09, "wall"), (0.11, "object"), (1.49, "object"), (1.51, "wall")]
)
def test_behind_means_10_cm_to_1_5_m_beyond_its_back_face(depth, kind):
    strip = slab()
    back_face = 4.0 + 0.02
    behind = np.c_[np.full(20, back_face + depth), np.linspace(0.6, 2.4, 20), np.full(20, 0.3)]
    assert OPEN_BEHIND_M == (0.1, 1.5)
    assert kind_after(strip, np.concatenate([own_points(strip), behind])) == kind


def test_behind_is_along_the_slab_only():
    strip = slab()  # y from 0.5 to 2.5
    beside = np.c_[np.full(20, 4.5), np.linspace(2.55, 3.0, 20), np.full(20, 1.0)]
    assert kind_after(strip, np.concatenate([own_points(strip), beside])) == "wall"
    strip = slab()
    along = np.c_[np.full(20, 4.5), np.linspace(2.0, 2.45, 20), np.full(20, 2.4)]  # any height counts
    assert kind_after(strip, np.concatenate([own_points(strip), along])) == "object"


def test_behind_is_away_from_the_viewpoint():
    strip = slab()
    room_side = np.c_[np.full(20, 3.5), np.linspace(0.6, 2.4, 20), np.full(20, 1.0)]  # in front of it
    points = np.concatenate([own_points(strip), room_side])
    assert kind_after(strip, points) == "wall"
    seen_from_outside = slab()
    assert kind_after(seen_from_outside, points, viewpoint=np.array([6.0, 1.5, 1.2])) == "object"


@pytest.mark.parametrize(
    ("length", "thick", "kind"),
    [
        (1.2, 0.04, "wall"),
        (1.18, 0.04, "object"),
        (2.0, 0.3, "wall"),
        (2.0, 0.32, "object"),
        (3.9, 0.32, "object"),
        (4.0, 0.32, "wall"),  # as long as a room's wall: up to 1 m deep
        (4.0, 1.0, "wall"),
        (4.0, 1.02, "object"),
    ],
)
def test_it_must_be_thin_or_as_long_as_a_wall(length, thick, kind):
    assert OPEN_SLABS == ((0.3, 1.2), (1.0, 4.0))
    strip = slab(length=length, thick=thick, z=(0.0, 1.6))  # its height above its depth: upright
    assert kind_after(strip, own_points(strip)) == kind


@pytest.mark.parametrize(("deg", "kind"), [(11.0, "wall"), (12.0, "object")])
def test_it_must_be_upright(deg, kind):
    t = np.radians(deg)  # the slab's normal (x) tipped towards up about y
    rotation = np.array([[np.cos(t), 0.0, -np.sin(t)], [0.0, 1.0, 0.0], [np.sin(t), 0.0, np.cos(t)]])
    strip = slab(rotation=rotation)
    assert kind_after(strip, own_points(strip)) == kind


def test_other_kinds_and_short_or_level_slabs_keep_their_kind():
    floor = slab(kind="floor")
    top = Cuboid([2.0, 1.5, 0.75], [0.6, 1.0, 0.02], np.eye(3))  # a table top: level
    open_behind_is_wall([floor, top], own_points(floor), UP, INSIDE)
    assert (floor.kind, top.kind) == ("floor", "object")


def test_a_room_on_its_side_reads_up_from_its_up():
    # the same strip with up along +x: its normal is y, its length along z
    strip = Cuboid([0.8, 4.0, 1.5], [0.3, 0.02, 1.0], np.eye(3))
    open_behind_is_wall([strip], own_points(strip), np.array([1.0, 0.0, 0.0]), np.array([1.2, 1.5, 2.0]))
    assert strip.kind == "wall"

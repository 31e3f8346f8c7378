"""Which side of a bare cloud's surface was seen: rays through an occupancy grid of the points, in numbers (a
ray's free length, its cap, leaving the grid), and the free side of a plate standing in a closed room, just
either side of the margin that decides."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.geometry.free_side import _cone, _free_lengths, free_side_normals

INSIDE = np.array([3.6, 2.0, 1.5])


def box_room(step: float = 0.1) -> np.ndarray:
    """Points on the six faces of the box [0, 4] x [0, 4] x [0, 3] m, ``step`` apart."""
    g, h = np.arange(0, 4.0001, step), np.arange(0, 3.0001, step)
    a, b = np.meshgrid(g, g, indexing="ij")
    faces = [np.c_[a.ravel(), b.ravel(), np.full(a.size, z)] for z in (0.0, 3.0)]
    a, b = np.meshgrid(g, h, indexing="ij")
    faces += [np.c_[a.ravel(), np.full(a.size, y), b.ravel()] for y in (0.0, 4.0)]
    faces += [np.c_[np.full(a.size, x), a.ravel(), b.ravel()] for x in (0.0, 4.0)]
    return np.concatenate(faces)


def plate(x: float, step: float = 0.1) -> np.ndarray:
    """A 1 x 1 m plate on the plane x = ``x``, facing along x."""
    a, b = np.meshgrid(np.arange(1.5, 2.5001, step), np.arange(1.0, 2.0001, step), indexing="ij")
    return np.c_[np.full(a.size, x), a.ravel(), b.ravel()]


def test_a_ray_travels_to_the_first_occupied_cell_up_to_its_cap():
    occupied = np.zeros((20, 20, 20), dtype=np.bool_)
    occupied[15] = True  # a wall filling the cells 1.5 <= x < 1.6
    point = np.array([[0.55, 1.0, 1.0]])
    dirs = np.array([[[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0], [0.0, 1.0, 0.0]]])
    out = np.empty((1, 3))
    _free_lengths(point, dirs, occupied, np.zeros(3), 0.1, 0.2, 2.0, out)
    # along +x the ray steps half a cell at a time from 0.2 m: x = 1.5 at t = 0.95; along -x and +y it
    # leaves the grid first: nothing is known to be free there
    assert out[0].tolist() == pytest.approx([0.95, 0.0, 0.0])
    _free_lengths(point, dirs, occupied, np.zeros(3), 0.1, 0.2, 0.5, out)
    assert out[0, 0] == pytest.approx(0.5)  # capped: free as far as it looks


@pytest.mark.parametrize(("x", "flipped"), [(2.6, False), (2.8, True), (3.0, True)])
def test_a_plate_faces_the_side_where_rays_cross_the_room(x, flipped):
    # the plate's normals start towards the point inside (+x); behind it (-x) rays cross up to 2 m of the
    # room, in front they meet the wall x = 4 after 4 - x m: flipped when the back is freer by a quarter of
    # the 2 m the rays look (2.6: 1.6 m in front against 2 m behind; 2.8: 1.36 m against 2 m)
    room, part = box_room(), plate(x)
    pts = np.concatenate([room, part])
    normals = np.zeros_like(pts)
    normals[len(room) :] = [1.0, 0.0, 0.0]
    normals[: len(room)] = [0.0, 0.0, 1.0]
    out = free_side_normals(pts, normals, INSIDE, 0.1)
    centre = len(room) + int(np.argmin(np.linalg.norm(part - [x, 2.0, 1.5], axis=1)))
    assert out[centre].tolist() == ([-1.0, 0.0, 0.0] if flipped else [1.0, 0.0, 0.0])
    floor = np.flatnonzero(
        (pts[:, 2] == 0.0) & (np.abs(pts[:, 0] - 2.0) < 0.5) & (np.abs(pts[:, 1] - 2.0) < 0.5)
    )
    assert (out[floor] == [0.0, 0.0, 1.0]).all()  # the floor faces the room: below it nothing is known
    given_reversed = free_side_normals(pts, -normals, INSIDE, 0.1)
    assert np.array_equal(given_reversed[len(room) :], out[len(room) :])  # the sign given does not matter


def test_a_surface_facing_another_close_by_is_seen_from_its_other_side():
    # two plates 0.5 m apart in the middle of the room: rays from the first towards the point inside meet
    # the second, rays behind it cross 2 m of the room
    room, first, second = box_room(), plate(2.0), plate(2.5)
    pts = np.concatenate([room, first, second])
    normals = np.zeros_like(pts)
    normals[len(room) :] = [1.0, 0.0, 0.0]
    out = free_side_normals(pts, normals, INSIDE, 0.1)
    centre = len(room) + int(np.argmin(np.linalg.norm(first - [2.0, 2.0, 1.5], axis=1)))
    assert out[centre].tolist() == [-1.0, 0.0, 0.0]


def test_rays_stop_at_occupied_cells_on_every_axis_and_side():
    occupied = np.zeros((20, 20, 20), dtype=np.bool_)
    occupied[0], occupied[:, 0], occupied[:, :, 0] = True, True, True  # walls in the first cell of each axis
    point = np.array([[1.05, 1.05, 1.05]])
    dirs = -np.eye(3)[None]  # towards each of those walls
    out = np.empty((1, 3))
    _free_lengths(point, dirs, occupied, np.zeros(3), 0.1, 0.2, 2.0, out)
    # half-cell steps from 0.2 m: at t = 0.95 the ray is at 0.1 m, which rounds into the first cell
    assert out[0].tolist() == pytest.approx([0.95, 0.95, 0.95])


def test_a_cone_is_the_normal_and_four_directions_at_its_angle():
    rng = np.random.default_rng(6)
    n = rng.normal(size=(50, 3))
    n /= np.linalg.norm(n, axis=1, keepdims=True)
    n[0] = [1.0, 0.0, 0.0]  # along the first helper axis
    for angle in (30.0, 10.0):
        dirs = _cone(n, angle)
        assert dirs.shape == (50, 5, 3) and np.allclose(dirs[:, 0], n)
        assert np.allclose(np.linalg.norm(dirs, axis=2), 1.0)
        assert np.allclose(np.einsum("nkj,nj->nk", dirs[:, 1:], n), np.cos(np.deg2rad(angle)))
        tilt = dirs[:, 1:] - np.cos(np.deg2rad(angle)) * n[:, None]
        assert np.allclose(tilt[:, 0], -tilt[:, 1]) and np.allclose(tilt[:, 2], -tilt[:, 3])
        assert np.allclose(np.einsum("nj,nj->n", tilt[:, 0], tilt[:, 2]), 0.0)  # two perpendicular tilts

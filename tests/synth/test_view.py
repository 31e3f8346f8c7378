"""Camera rays (cuboidcli.synth.rays) and the choice of the camera's orientation (cuboidcli.synth.view)."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.synth.mesh import build_soup
from cuboidcli.synth.placement import Occupancy
from cuboidcli.synth.rays import pixel_directions
from cuboidcli.synth.render import RayCaster
from cuboidcli.synth.room import build_room
from cuboidcli.synth.view import choose_view, look_rotation
from cuboidcli.synth.world import World, rot_z

CAM = Camera(100.0, 90.0, 40.0, 29.5, 80, 60)


def test_pixel_directions_have_unit_z_through_pixel_centres():
    d = pixel_directions(CAM)
    assert d.shape == (60, 80, 3) and d.dtype == np.float32 and not d.flags.writeable
    assert (d[..., 2] == 1).all()
    # pixel (u, v) = (column, row) looks along ((u - cx) / fx, (v - cy) / fy, 1): backproject's convention
    assert d[0, 0, :2] == pytest.approx([-0.4, -29.5 / 90.0])
    assert d[59, 79, :2] == pytest.approx([39.0 / 100.0, 29.5 / 90.0])
    assert np.allclose(CAM.backproject(np.ones((60, 80))), d, atol=1e-7)
    coarse = pixel_directions(CAM, step=8)
    assert coarse.shape == (8, 10, 3) and np.array_equal(coarse, d[::8, ::8])


@pytest.mark.parametrize("yaw, pitch, roll", [(0.0, 0.0, 0.0), (0.7, -0.3, 0.04), (-2.5, 0.15, -0.05)])
def test_look_rotation_is_an_opencv_camera_in_a_z_up_world(yaw, pitch, roll):
    r = look_rotation(yaw, pitch, roll)
    assert np.allclose(r.T @ r, np.eye(3)) and np.linalg.det(r) == pytest.approx(1.0)
    right, down, forward = r.T
    assert forward == pytest.approx([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)])
    # roll turns about the viewing direction, tilting the right axis out of the horizontal plane
    assert right[2] == pytest.approx(-np.sin(roll) * np.cos(pitch), abs=1e-12)
    assert down[2] < 0  # y points down-ish for small roll and pitch
    if roll == 0.0:
        assert right[2] == pytest.approx(0.0, abs=1e-15)
    if yaw == pitch == roll == 0.0:
        assert np.allclose(r, [[0.0, 0.0, 1.0], [-1.0, 0.0, 0.0], [0.0, -1.0, 0.0]])


def _room_with_boxes_on_one_side():
    """A closed room without furniture (the first 4-wall room without a doorway), then three boxes at its
    +x end; the camera stands in the middle."""
    for seed in range(100):
        world = World()
        room = build_room(world, Occupancy(), np.random.default_rng(seed))
        if all(s.present and s.doorway is None for s in room.sides):
            break
    sx, sy, _ = room.size
    for k, y in enumerate((sy / 2 - 0.7, sy / 2, sy / 2 + 0.7)):
        oid = world.new_object("cabinet")
        world.add_box(oid, "body", [sx - 0.4, y, 0.4 + 0.1 * k], [0.25, 0.25, 0.4 + 0.1 * k], rot_z(0.0), 0)
    position = np.array([sx / 2, sy / 2, 1.4])
    return world, position


def test_choose_view_looks_at_the_furniture():
    world, position = _room_with_boxes_on_one_side()
    soup = build_soup(world)
    caster = RayCaster(soup.vertices, soup.faces, threads=1)
    cam = Camera.preset("nyu").scaled(0.25)
    for seed in range(3):
        rot = choose_view(caster, cam, position, soup, world, np.random.default_rng(seed), (-10.0, 0.0), 0.0)
        forward = rot[:, 2]
        assert forward[0] > 0.5  # towards the +x end, where the boxes are
        assert -np.sin(np.radians(10.0)) - 1e-9 <= forward[2] <= 1e-9  # the pitch range
        assert abs(rot[2, 0]) < 1e-12  # no roll with sigma 0
        hits = caster.cast(cam, rot, position)
        seen = set(soup.object_id[hits.face[hits.hit]]) - {
            o.id for o in world.objects if o.category != "cabinet"
        }
        assert len(seen) == 3


def test_choose_view_falls_back_to_the_best_view_of_an_empty_room():
    world, position = _room_with_boxes_on_one_side()
    world.parts = world.parts[:-3]  # no furniture: no view passes, the best one is returned anyway
    world.objects = world.objects[:-3]
    soup = build_soup(world)
    caster = RayCaster(soup.vertices, soup.faces, threads=1)
    rot = choose_view(
        caster, Camera.preset("nyu").scaled(0.1), position, soup, world, np.random.default_rng(0)
    )
    assert rot is not None and np.allclose(rot.T @ rot, np.eye(3))

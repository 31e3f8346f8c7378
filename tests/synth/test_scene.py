"""One frame (cuboidcli.synth.scene): what a Scene holds, the camera pose it records, seeds and options."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.synth import SceneOptions, SensorOptions, generate_scene, materials, render_world
from cuboidcli.synth.view import look_rotation
from cuboidcli.synth.world import World, rot_z
from tests.synth import helpers

TINY = Camera.preset("nyu").scaled(0.2)  # 128x96


@pytest.fixture(scope="module")
def scene():
    return generate_scene(
        4, TINY, SceneOptions(camera_height_m=(1.5, 1.5), pitch_deg=(-12.0, -12.0), roll_sigma_deg=0.0)
    )


def test_a_scene_holds_what_its_docstring_lists(scene):
    assert scene.camera == TINY
    assert scene.depth_m.shape == scene.depth_clean_m.shape == scene.instances.shape == (96, 128)
    assert scene.depth_m.dtype == scene.depth_clean_m.dtype == np.float32
    assert (
        scene.rgb.shape == (96, 128, 3) and scene.rgb.dtype == np.uint8 and scene.instances.dtype == np.int32
    )
    assert scene.seed == [4]
    assert set(scene.room) == {"size_m", "walls", "doorway"} and len(scene.room["walls"]) == 4
    assert scene.room["doorway"] is None or scene.room["walls"][scene.room["doorway"][0]]
    ids = [o["id"] for o in scene.objects]
    assert ids == sorted(ids) and set(np.unique(scene.instances)) - {0} == set(ids)
    assert {o["kind"] for o in scene.objects} <= {"boxes", "mesh"}
    assert {c.extras["object"] for c in scene.cuboids} == {
        o["id"] for o in scene.objects if o["kind"] == "boxes"
    }
    # 0 means no surface in the exact map, a hole in the sensor's
    assert ((scene.depth_clean_m == 0) == (scene.instances == 0)).all()
    assert ((scene.depth_m > 0) <= (scene.depth_clean_m > 0)).all()


def test_the_pose_is_the_configured_one(scene):
    pose = scene.world_from_camera
    rotation, position = pose[:3, :3], pose[:3, 3]
    assert pose.shape == (4, 4) and pose[3].tolist() == [0.0, 0.0, 0.0, 1.0]
    assert np.allclose(rotation.T @ rotation, np.eye(3)) and np.linalg.det(rotation) == pytest.approx(1.0)
    sx, sy, _ = scene.room["size_m"]
    assert (
        0.7 <= position[0] <= sx - 0.7
        and 0.7 <= position[1] <= sy - 0.7
        and position[2] == pytest.approx(1.5)
    )
    assert np.degrees(np.arcsin(rotation[2, 2])) == pytest.approx(-12.0)  # pitch of the optical axis
    assert rotation[2, 0] == pytest.approx(0.0, abs=1e-12)  # no roll
    yaw = np.arctan2(rotation[1, 2], rotation[0, 2])
    assert np.allclose(rotation, look_rotation(yaw, np.radians(-12.0), 0.0))


def test_seeds_threads_and_options():
    a = generate_scene(9, TINY)
    assert np.array_equal(generate_scene([9], TINY).depth_m, a.depth_m)  # an int is a one-element sequence
    b = generate_scene(9, TINY, SceneOptions(threads=1))  # results do not depend on the thread count
    for name in ("depth_m", "depth_clean_m", "rgb", "instances"):
        assert np.array_equal(getattr(a, name), getattr(b, name)), name
    # (numpy's SeedSequence pads with zeros: (9, 0) is the seed 9 itself, so a dataset's frame 0 is
    # generate_scene(dataset seed); other frames differ)
    assert not np.array_equal(generate_scene((9, 1), TINY).depth_clean_m, a.depth_clean_m)
    d = SceneOptions(threads=3).to_dict()
    assert "threads" not in d and d["sensor"] == SensorOptions().__dict__ and d["furniture"] == (3, 9)
    # no colour noise, or no shadows: the image changes, the geometry does not
    for changed in (SceneOptions(rgb_noise=0.0), SceneOptions(shadows=False)):
        plain = generate_scene(9, TINY, changed)
        assert np.array_equal(plain.depth_m, a.depth_m) and np.array_equal(plain.instances, a.instances)
        assert not np.array_equal(plain.rgb, a.rgb), changed


def test_render_world_puts_the_boxes_into_the_camera_frame():
    world = World()
    mat = world.add_material(materials.sample("wall", np.random.default_rng(0)))
    wall = world.new_object("wall")
    world.add_box(wall, "slab", [5.0, 0.0, 1.5], [0.025, 4.0, 1.5], np.eye(3), mat)
    box = world.new_object("cabinet")
    world.add_box(box, "body", [3.0, 0.3, 0.5], [0.3, 0.4, 0.5], rot_z(0.3), mat)
    hidden = world.new_object("box")
    world.add_box(hidden, "box", [6.0, 0.0, 0.5], [0.2, 0.2, 0.2], np.eye(3), mat)  # behind the wall
    world.lights.append((np.array([2.0, 0.0, 2.8]), 3.0))
    rotation = look_rotation(0.05, -0.2, 0.0)
    position = np.array([0.0, 0.2, 1.4])
    scene = render_world(world, TINY, rotation, position, SceneOptions(sensor=SensorOptions.clean()), seed=3)
    assert scene.seed == [3] and np.allclose(scene.world_from_camera[:3, :3], rotation)
    assert [o["category"] for o in scene.objects] == ["wall", "cabinet"]  # the hidden box is left out
    by_category = {c.extras["category"]: c for c in scene.cuboids}
    cab = by_category["cabinet"]
    assert np.allclose(cab.center, rotation.T @ ([3.0, 0.3, 0.5] - position))
    assert np.allclose(cab.rotation, rotation.T @ rot_z(0.3)) and np.allclose(cab.half_size, [0.3, 0.4, 0.5])
    assert cab.extras["part"] == "body" and cab.extras["object"] == box
    # the camera-frame cuboids, ray cast in the camera frame, give the rendered depth
    rays = helpers.pixel_rays(TINY).reshape(-1, 3)
    t, _ = helpers.cast_boxes(np.zeros(3), rays, [(c.center, c.half_size, c.rotation) for c in scene.cuboids])
    t = np.where(np.isfinite(t), t, 0.0).reshape(96, 128)
    assert np.abs(t - scene.depth_clean_m).max() < 1e-4
    in_range = (scene.depth_clean_m >= 0.4) & (scene.depth_clean_m <= 10.0)
    assert np.array_equal(scene.depth_m[in_range], scene.depth_clean_m[in_range])  # the clean sensor

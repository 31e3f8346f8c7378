"""Synthetic scenes: exact rendering against the ground truth, sensor model, determinism, dataset layout."""

import json

import numpy as np
import pytest
import torch

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid, stack_cuboids
from cuboidcli.geometry.kernels import cuboid_sq_distance, to_local
from cuboidcli.io.dataset import list_frames
from cuboidcli.io.depth import read_depth
from cuboidcli.io.result import read_result
from cuboidcli.synth import SceneOptions, SensorOptions, generate_scene, render_boxes, split_of, write_dataset
from cuboidcli.synth.sensor import fill_holes, projector_shadow, simulate_depth

SMALL = Camera.preset("nyu").scaled(0.25)  # 160x120 keeps the tests fast


def _distance_to_boxes(points: np.ndarray, boxes: list[Cuboid]) -> np.ndarray:
    """Distance (N,) of points (N, 3) to the nearest of the boxes' surfaces, metres."""
    c, a, r = stack_cuboids(boxes, dtype=torch.float64)
    return cuboid_sq_distance(to_local(torch.from_numpy(points), c, r), a).amin(0).sqrt().numpy()


@pytest.fixture(scope="module")
def scenes():
    return {seed: generate_scene(seed, SMALL) for seed in (0, 1, 2)}


def test_render_boxes_is_exact():
    near = Cuboid([0.0, 0.0, 3.0], [0.5, 0.5, 0.5], np.eye(3))
    c, s = np.cos(0.6), np.sin(0.6)
    far = Cuboid([0.8, 0.3, 5.0], [0.6, 0.4, 0.7], [[c, 0.0, s], [0.0, 1.0, 0.0], [-s, 0.0, c]])
    depth, instance = render_boxes([near, far], SMALL)
    assert depth.shape == instance.shape == (120, 160) and depth.dtype == np.float32
    # the principal point looks straight at the near box's front face, z = 2.5 m
    u, v = int(round(SMALL.cx)), int(round(SMALL.cy))
    assert instance[v, u] == 1 and depth[v, u] == pytest.approx(2.5, abs=1e-5)
    assert (instance == 2).sum() > 200 and (instance == 0).sum() > 1000
    assert np.all(depth[instance == 0] == 0)
    points = SMALL.backproject(depth).reshape(-1, 3)
    for k, box in enumerate([near, far], start=1):
        d = _distance_to_boxes(points[instance.ravel() == k], [box])
        assert d.max() < 1e-5


def test_render_boxes_noise_is_seeded_and_kinect_like():
    box = Cuboid([0.0, 0.0, 4.0], [3.0, 3.0, 0.5], np.eye(3))  # a wall-like face at 3.5 m fills the view
    clean, _ = render_boxes([box], SMALL)
    a, inst = render_boxes([box], SMALL, noise=True, seed=3)
    b, _ = render_boxes([box], SMALL, noise=True, seed=3)
    c, _ = render_boxes([box], SMALL, noise=True, seed=4)
    assert np.array_equal(a, b) and not np.array_equal(a, c)
    assert (inst == 1).all()
    valid = a > 0
    assert 0.8 < valid.mean() < 1.0  # holes, but mostly valid
    mm = a[valid] * 1000.0
    assert np.allclose(mm, np.round(mm), atol=1e-3)  # quantised to millimetres
    err = a[valid] - clean[valid]
    assert 0.5 * 0.0015 * 3.5**2 < err.std() < 1.5 * 0.0015 * 3.5**2  # sigma = 1.5 mm * z^2


def test_scene_depth_lies_on_ground_truth_cuboids(scenes):
    for scene in scenes.values():
        points = scene.camera.backproject(scene.depth_clean_m).reshape(-1, 3)
        instances = scene.instances.ravel()
        n_box_objects = 0
        for obj in scene.objects:
            boxes = [c for c in scene.cuboids if c.extras["object"] == obj["id"]]
            assert obj["visible_px"] == (instances == obj["id"]).sum()
            if obj["kind"] == "mesh":
                assert not boxes  # clutter has an instance but no cuboid
                continue
            n_box_objects += 1
            assert boxes and all(b.extras["category"] == obj["category"] for b in boxes)
            assert _distance_to_boxes(points[instances == obj["id"]], boxes).max() < 1e-4
        assert n_box_objects >= 3


def test_scene_tags_slabs_and_camera(scenes):
    for scene in scenes.values():
        cats = {c.extras["category"] for c in scene.cuboids}
        assert cats & {"floor", "wall", "ceiling"}
        for c in scene.cuboids:
            assert {"object", "category", "part", "visible_px"} <= set(c.extras) and c.extras[
                "visible_px"
            ] > 0
            assert np.allclose(c.rotation.T @ c.rotation, np.eye(3), atol=1e-9)
            if c.extras["category"] in ("floor", "wall", "ceiling"):
                assert c.half_size.min() == pytest.approx(0.025)  # 5 cm slabs
        pose = scene.world_from_camera
        assert 1.2 <= pose[2, 3] <= 1.8  # camera height above the floor
        pitch = np.degrees(np.arcsin(pose[2, 2]))  # the optical axis' elevation
        assert -30.0 <= pitch <= 10.0
        assert abs(pose[2, 0]) < np.sin(np.radians(5.01))  # small roll: the x axis stays level
        d = scene.depth_clean_m[scene.depth_clean_m > 0]
        assert d.min() > 0.4 and 1.0 <= np.median(d) <= 7.0


def test_generation_is_deterministic(scenes):
    again = generate_scene(1, SMALL)
    first = scenes[1]
    for name in ("depth_m", "depth_clean_m", "rgb", "instances"):
        assert np.array_equal(getattr(first, name), getattr(again, name))
    assert [c.to_json(i) for i, c in enumerate(first.cuboids)] == [
        c.to_json(i) for i, c in enumerate(again.cuboids)
    ]
    assert not np.array_equal(scenes[0].depth_m, scenes[1].depth_m)
    # switching the sensor noise off changes only the depth, not the room or the view
    quiet = generate_scene(1, SMALL, SceneOptions(sensor=SensorOptions.clean()))
    assert np.array_equal(quiet.instances, first.instances) and np.array_equal(quiet.rgb, first.rgb)
    in_range = (first.depth_clean_m >= 0.4) & (first.depth_clean_m <= 10.0)
    assert np.array_equal(quiet.depth_m[in_range], first.depth_clean_m[in_range])


def test_full_size_frame_has_texture_and_holes():
    scene = generate_scene(7)
    assert scene.rgb.shape == (480, 640, 3) and scene.rgb.dtype == np.uint8
    assert scene.depth_m.shape == (480, 640) and scene.instances.dtype == np.int32
    assert scene.rgb.std() > 10.0  # shaded and textured, not flat
    holes = (scene.depth_m == 0) & (scene.depth_clean_m > 0)
    assert 0.002 < holes.mean() < 0.2


def test_projector_shadow_width():
    depth = np.full((4, 100), 3.0)
    depth[:, 50:60] = 1.0  # a foreground strip 1 m away in front of a 3 m background
    shadow = projector_shadow(depth, fx_px=500.0, baseline_m=0.075)
    # width fx * b * (1/1 - 1/3) = 25 px, left of the strip (the projector sits to the right)
    assert shadow[:, 26:50].all()
    assert not shadow[:, :26].any() and not shadow[:, 50:].any()


def test_fill_holes_keeps_valid_pixels_and_interpolates():
    ramp = np.tile(np.linspace(1.0, 3.0, 64, dtype=np.float32), (48, 1))
    rng = np.random.default_rng(0)
    holes = rng.random(ramp.shape) < 0.3
    holes[10:20, 20:40] = True
    filled = fill_holes(np.where(holes, 0.0, ramp).astype(np.float32))
    assert (filled > 0).all()
    assert np.array_equal(filled[~holes], ramp[~holes])
    assert np.abs(filled - ramp).max() < 0.25


def test_sensor_switches():
    cam = Camera(100.0, 100.0, 31.5, 23.5, 64, 48)
    depth = np.full((48, 64), 2.0, np.float32)
    facing = np.zeros((48, 64, 3), np.float32)
    facing[..., 2] = -1.0
    rng = np.random.default_rng(0)
    assert np.array_equal(simulate_depth(depth, facing, cam, SensorOptions.clean(), rng), depth)
    noise_only = SensorOptions(grazing=False, boundary=False, dropout=False, quantize_m=0.0)
    noisy = simulate_depth(depth, facing, cam, noise_only, rng)
    assert noisy.std() == pytest.approx(0.0015 * 4.0, rel=0.15)
    grazing = np.zeros((48, 64, 3), np.float32)
    grazing[..., 0] = 1.0  # normal along x: the central columns see these surfaces edge-on
    only_grazing = SensorOptions(noise=False, boundary=False, dropout=False)
    seen = simulate_depth(depth, grazing, cam, only_grazing, rng)
    assert (seen[:, 28:36] == 0).all()  # |cos| < 0.05: always dropped
    assert (seen[:, :4] == 2.0).all()  # |cos| > 0.25 at the image border: always kept
    far = np.full((48, 64), 12.0, np.float32)
    assert (simulate_depth(far, facing, cam, SensorOptions.clean(), rng) == 0).all()  # beyond 10 m
    dense = simulate_depth(depth, facing, cam, SensorOptions(inpaint=True), rng)
    assert (dense > 0).all()


def test_split_rule():
    assert [split_of(i) for i in range(10)] == ["train"] * 8 + ["val", "test"]
    assert split_of(18) == "val" and split_of(29) == "test" and split_of(1230) == "train"


def test_dataset_round_trips_through_the_reader(tmp_path):
    names = write_dataset(tmp_path, 3, seed=5, camera=SMALL)
    assert names == ["000000", "000001", "000002"]
    frames = list_frames(tmp_path)
    assert [f.name for f in frames] == names
    assert [f.name for f in list_frames(tmp_path, split="train")] == names
    assert json.loads((tmp_path / "splits.json").read_text()) == {"train": names, "val": [], "test": []}
    for i, frame in enumerate(frames):
        scene = generate_scene((5, i), SMALL)
        assert frame.camera == SMALL and frame.depth_scale == 0.001
        assert np.allclose(frame.depth_m(), np.round(scene.depth_m * 1000) / 1000, atol=1e-6)
        assert np.array_equal(frame.rgb(), scene.rgb)
        gt = frame.gt_cuboids()
        assert len(gt) == len(scene.cuboids)
        assert gt[0].extras == scene.cuboids[0].extras
        assert np.allclose(gt[-1].center, scene.cuboids[-1].center)
        result = read_result(frame.cuboids_path)
        assert result.settings["seed"] == [5, i] and result.extras["objects"] == scene.objects
        import cv2

        inst = cv2.imread(str(frame.instances_path), cv2.IMREAD_UNCHANGED)
        assert inst.dtype == np.uint16 and np.array_equal(inst, scene.instances)


def test_embedded_sample_matches_its_cuboids():
    from importlib.resources import files

    sample = files("cuboidcli") / "data" / "sample"
    cam_d = json.loads((sample / "camera.json").read_text())
    cam = Camera.from_dict(cam_d)
    assert (cam.width, cam.height, cam_d["depth_scale"]) == (640, 480, 0.001)
    depth = read_depth(sample / "sample_depth.png", cam_d["depth_scale"])
    assert depth.shape == (480, 640)
    valid = depth > 0
    assert 0.8 < valid.mean() < 0.995  # realistic holes
    gt = read_result(sample / "sample_cuboids.json").cuboids
    cats = {c.extras["category"] for c in gt}
    assert {"table", "cabinet", "box"} <= cats and cats & {"bed", "sofa"}
    points = cam.backproject(depth, step=4).reshape(-1, 3)
    points = points[points[:, 2] > 0]
    d = _distance_to_boxes(points, gt)
    assert np.mean(d < 0.05) > 0.9  # noisy depth on the boxes, except the non-box clutter

"""Ray casting (cuboidcli.synth.render) against an independent numpy ray caster (helpers.py): the rendered
scenes, their instance images and the ground-truth cuboids agree."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.synth import generate_scene, render_boxes
from cuboidcli.synth.mesh import box_mesh
from cuboidcli.synth.render import RayCaster, cast_boxes
from tests.synth import helpers

SMALL = Camera.preset("nyu").scaled(0.25)  # 160x120


@pytest.fixture(scope="module")
def scenes():
    return [generate_scene(seed, SMALL) for seed in (0, 2, 11)]  # 11 sees out through a missing wall


def _oracle(scene):
    """Depth (H, W) and hit cuboid index (H, W) of the scene's ground-truth cuboids, numpy ray cast."""
    rays = helpers.pixel_rays(scene.camera).reshape(-1, 3)
    boxes = [(c.center, c.half_size, c.rotation) for c in scene.cuboids]
    t, index = helpers.cast_boxes(np.zeros(3), rays, boxes)
    shape = scene.depth_clean_m.shape
    return np.where(np.isfinite(t), t, 0.0).reshape(shape), index.reshape(shape)


def test_scene_depth_is_a_ray_cast_of_its_cuboids_where_no_clutter_covers_it(scenes):
    seen_nothing = 0
    for scene in scenes:
        depth, index = _oracle(scene)
        kind = {o["id"]: o["kind"] for o in scene.objects}
        owner = np.array([c.extras["object"] for c in scene.cuboids])
        on_boxes = np.isin(scene.instances, [i for i, k in kind.items() if k == "boxes"])
        on_clutter = np.isin(scene.instances, [i for i, k in kind.items() if k == "mesh"])
        nothing = scene.instances == 0
        assert on_boxes.mean() > 0.5 and (on_boxes | on_clutter | nothing).all()
        seen_nothing += int(nothing.sum())
        # where a box object is seen, the first cuboid along the ray is at the rendered depth and belongs
        # to that object (pixels on a shared edge may go to either of two touching boxes)
        assert np.abs(depth[on_boxes] - scene.depth_clean_m[on_boxes]).max() < 2e-4
        assert np.mean(owner[index[on_boxes]] == scene.instances[on_boxes]) > 0.995
        # clutter hides the boxes behind it; nothing is seen where no cuboid is either
        assert (
            np.where(index[on_clutter] >= 0, depth[on_clutter], np.inf) > scene.depth_clean_m[on_clutter]
        ).all()
        assert (index[nothing] >= 0).sum() <= 0.001 * nothing.sum()
        assert (scene.depth_clean_m[nothing] == 0).all()
    assert seen_nothing > 100


def test_visible_pixel_counts_match_the_instance_image(scenes):
    for scene in scenes:
        _, index = _oracle(scene)
        for obj in scene.objects:
            assert obj["visible_px"] == (scene.instances == obj["id"]).sum()
            parts = [(k, c) for k, c in enumerate(scene.cuboids) if c.extras["object"] == obj["id"]]
            if obj["kind"] != "boxes":
                continue
            # every pixel of a box object sees one of its parts
            assert sum(c.extras["visible_px"] for _, c in parts) == obj["visible_px"]
            for k, c in parts:  # and that part is where the oracle finds it (up to shared edges)
                count = int(((index == k) & (scene.instances == obj["id"])).sum())
                assert abs(count - c.extras["visible_px"]) <= 3 + 0.02 * count, (obj, c.extras)


def test_render_boxes_agrees_with_the_oracle_on_a_whole_scene(scenes):
    scene = scenes[0]
    depth, index = _oracle(scene)
    rendered, instance = render_boxes(scene.cuboids, SMALL)
    both = (instance > 0) & (index >= 0)
    assert both.mean() > 0.9 and np.mean((instance > 0) == (index >= 0)) > 0.999
    assert np.abs(rendered[both] - depth[both]).max() < 1e-4
    assert np.mean(instance[both] - 1 == index[both]) > 0.99
    # with the sensor model the visibility stays the exact one
    noisy, noisy_instance = render_boxes(scene.cuboids, SMALL, noise=True, seed=1)
    assert np.array_equal(noisy_instance, instance) and not np.array_equal(noisy, rendered)


def test_ray_caster_normals_steps_and_occlusion():
    v, f = box_mesh([0.2, -0.1, 3.0], [0.5, 0.4, 0.5], np.eye(3))
    caster = RayCaster(v, f, threads=1)
    hits = caster.cast(SMALL)
    assert hits.depth_m.dtype == np.float32 and hits.face.dtype == np.int64
    hit = hits.hit
    assert hit.any() and not hit.all() and (hits.face[~hit] == -1).all() and (hits.depth_m[~hit] == 0).all()
    # the box's front face at z = 2.5 faces the camera: normal (0, 0, -1), unit, zero where nothing is hit
    assert np.allclose(hits.depth_m[hit], 2.5, atol=1e-5)
    assert np.allclose(hits.normal[hit], [0.0, 0.0, -1.0]) and (hits.normal[~hit] == 0).all()
    # seen from inside the box the back face's normal is still turned towards the camera
    inside = caster.cast(SMALL, np.eye(3), np.array([0.2, -0.1, 3.0]))
    assert inside.hit.all()
    rays = helpers.pixel_rays(SMALL)
    assert (np.einsum("hwk,hwk->hw", inside.normal, rays) < 0).all()
    assert np.allclose(np.linalg.norm(inside.normal, axis=-1), 1.0, atol=1e-6)
    # every step-th pixel is the full cast subsampled
    coarse = caster.cast(SMALL, step=8)
    assert np.array_equal(coarse.depth_m, hits.depth_m[::8, ::8]) and np.array_equal(
        coarse.face, hits.face[::8, ::8]
    )
    # a camera turned away (yaw by pi about y) sees nothing; a segment through the box is occluded
    turned = np.diag([-1.0, 1.0, -1.0])
    assert not caster.cast(SMALL, turned, np.zeros(3)).hit.any()
    origins = np.zeros((2, 3))
    directions = np.array([[0.2, -0.1, 4.0], [0.2, -0.1, 2.0]])  # through the box, and stopping short
    assert caster.occluded(origins, directions).tolist() == [True, False]


def test_cast_boxes_maps_faces_to_their_cuboid():
    boxes = [
        Cuboid([-0.6, 0.0, 2.0], [0.3, 0.3, 0.3], np.eye(3)),
        Cuboid([0.6, 0.0, 3.0], [0.3, 0.3, 0.3], np.eye(3)),
    ]
    hits, owner = cast_boxes(boxes, SMALL)
    assert owner.tolist() == [0] * 12 + [1] * 12
    seen = owner[hits.face[hits.hit]]
    u_left = SMALL.project(np.array([[-0.6, 0.0, 1.7]]))[0][0]
    assert seen.min() == 0 and seen.max() == 1
    assert owner[hits.face[int(round(u_left[1])), int(round(u_left[0]))]] == 0
    empty, none = cast_boxes([], SMALL, step=4)
    assert empty.depth_m.shape == (30, 40) and not empty.hit.any() and len(none) == 0

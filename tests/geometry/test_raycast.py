"""The numba ray caster of the overlays against a direct numpy statement of the same slab test."""

from __future__ import annotations

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.geometry.raycast import raycast_boxes


def reference(camera: Camera, centers, half_sizes, rotations):
    """Every pixel's ray against every box with numpy arrays (the statement the kernel must equal)."""
    u, v = camera.pixel_grid()
    d = np.stack([(u - camera.cx) / camera.fx, (v - camera.cy) / camera.fy, np.ones_like(u)], -1).reshape(
        -1, 3
    )
    depth = np.full(len(d), np.inf)
    label = np.full(len(d), -1)
    shade = np.zeros(len(d))
    for k, (c, a, rot) in enumerate(zip(centers, half_sizes, rotations, strict=True)):
        o = -rot.T @ c
        dl = d @ rot
        dl = np.where(np.abs(dl) < 1e-12, np.where(dl < 0, -1e-12, 1e-12), dl)
        t1, t2 = (-a - o) / dl, (a - o) / dl
        lo, hi = np.minimum(t1, t2), np.maximum(t1, t2)
        near, far = lo.max(1), hi.min(1)
        inside = near <= 0
        t = np.where(inside, far, near)
        axis = np.where(inside, hi.argmin(1), lo.argmax(1))
        hit = (near <= far) & (far > 0) & (t < depth)
        depth[hit], label[hit] = t[hit], k
        shade[hit] = (np.abs(dl[np.arange(len(d)), axis]) / np.linalg.norm(d, axis=1))[hit]
    return depth.reshape(u.shape), label.reshape(u.shape), shade.reshape(u.shape)


def test_the_kernel_equals_the_slab_test_on_random_boxes_including_one_around_the_camera():
    rng = np.random.default_rng(3)
    camera = Camera(80.0, 85.0, 40.3, 29.7, 81, 61)
    k = 7
    centers = rng.uniform([-1.5, -1.0, 1.5], [1.5, 1.0, 5.0], (k, 3))
    centers[0] = [0.0, 0.0, 0.2]  # the camera is inside box 0: it sees the box's far sides
    half = rng.uniform(0.1, 1.0, (k, 3))
    rots = np.stack([np.linalg.qr(rng.normal(size=(3, 3)))[0] for _ in range(k)])
    rots[1] = np.eye(3)  # axis-aligned: rays parallel to its slabs
    for boxes in (slice(1, k), slice(0, k)):  # without, then with, the box around the camera
        c, a, r = centers[boxes], half[boxes], rots[boxes]
        depth, label, shade = raycast_boxes(camera.fx, camera.fy, camera.cx, camera.cy, 81, 61, c, a, r)
        want_depth, want_label, want_shade = reference(camera, c, a, r)
        np.testing.assert_array_equal(label, want_label)
        np.testing.assert_allclose(depth, want_depth, rtol=1e-12)
        np.testing.assert_allclose(shade, want_shade, atol=1e-6)
        if boxes.start == 1:
            assert len(np.unique(label)) >= 4  # several boxes are seen, and some background
        else:
            assert (label == 0).mean() > 0.5  # mostly the inside of the box around the camera
    # No boxes: nothing is hit.
    none = raycast_boxes(camera.fx, camera.fy, camera.cx, camera.cy, 81, 61, centers[:0], half[:0], rots[:0])
    assert np.isinf(none[0]).all() and (none[1] == -1).all()

"""cuboidcli.io.dataset reads what cuboidcli.synth.dataset writes: the same cameras, depths (to the
millimetre), images, instance ids, ground-truth cuboids, camera poses and splits."""

from __future__ import annotations

import json

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.io.dataset import list_frames
from cuboidcli.io.depth import InputError
from cuboidcli.synth import SceneOptions, generate_scene, write_dataset

CAM = Camera(90.0, 95.0, 47.3, 35.8, 96, 72)  # not a preset, not a scaled one
OPTIONS = SceneOptions(furniture=(2, 5))
SEED = 11


@pytest.fixture(scope="module")
def dataset(tmp_path_factory):
    root = tmp_path_factory.mktemp("synth_dataset")
    names = write_dataset(root, 10, seed=SEED, camera=CAM, options=OPTIONS)
    return root, names


def test_frames_cameras_and_splits(dataset):
    root, names = dataset
    frames = list_frames(root)
    assert [f.name for f in frames] == names == [f"{i:06d}" for i in range(10)]
    for f in frames:
        assert f.camera == CAM and f.depth_scale == 0.001
        assert (
            f.depth_path == root / "depth" / f"{f.name}.png" and f.rgb_path == root / "rgb" / f"{f.name}.png"
        )
        assert f.cuboids_path.name == f.instances_path.name.replace(".png", ".json")
    assert [f.name for f in list_frames(root, split="train")] == names[:8]
    assert [f.name for f in list_frames(root, split="val")] == [names[8]]
    assert [f.name for f in list_frames(root, split="test")] == [names[9]]
    with pytest.raises(InputError, match="splits.json has only train, val, test"):
        list_frames(root, split="extra")


@pytest.mark.parametrize("index", [0, 8, 9])
def test_each_frame_reads_back_as_generated(dataset, index):
    root, names = dataset
    frame = list_frames(root)[index]
    scene = generate_scene((SEED, index), CAM, OPTIONS)
    depth = frame.depth_m()
    assert depth.dtype == np.float32 and depth.shape == (72, 96)
    # millimetre PNG: holes stay holes, every depth within half a millimetre
    assert np.array_equal(depth > 0, scene.depth_m > 0)
    assert np.abs(depth - scene.depth_m).max() <= 0.0005 + 1e-6
    assert np.array_equal(frame.rgb(), scene.rgb)
    instances = frame.instances()
    assert instances.dtype == np.int32 and np.array_equal(instances, scene.instances)
    gt = frame.gt_cuboids()
    assert len(gt) == len(scene.cuboids) > 0
    for read, made in zip(gt, scene.cuboids, strict=True):
        assert np.allclose(read.center, made.center, rtol=0, atol=1e-9)
        assert np.allclose(read.half_size, made.half_size, rtol=0, atol=1e-9)
        assert np.allclose(read.rotation, made.rotation, rtol=0, atol=1e-9)
        assert read.extras == made.extras
    assert np.allclose(frame.gt_world_from_camera(), scene.world_from_camera, rtol=0, atol=1e-12)


def test_a_fit_result_in_the_cuboids_folder_is_not_a_ground_truth_pose(dataset, tmp_path):
    root, _ = dataset
    frame = list_frames(root)[0]
    doc = json.loads(frame.cuboids_path.read_text())
    doc["gravity"] = {"up": [0.0, -1.0, 0.0]}  # what a fit writes next to its estimated pose
    (tmp_path / "depth").mkdir()
    (tmp_path / "cuboids").mkdir()
    (tmp_path / "depth" / "a.png").write_bytes(frame.depth_path.read_bytes())
    (tmp_path / "cuboids" / "a.json").write_text(json.dumps(doc))
    (tmp_path / "camera.json").write_text(json.dumps(CAM.to_dict()))
    (copy,) = list_frames(tmp_path)
    assert copy.camera == CAM and copy.rgb_path is None and copy.instances() is None
    assert copy.gt_world_from_camera() is None

"""Writing synthetic datasets (cuboidcli.synth.dataset): names, seeds, splits and files as documented.
Reading them back is tests/io/test_dataset.py."""

from __future__ import annotations

import json

import cv2
import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.synth import SceneOptions, generate_scene, write_dataset, write_frame
from cuboidcli.synth.dataset import depth_to_png_units, scene_result

CAM = Camera.preset("nyu").scaled(0.125)  # 80x60


def _files(root) -> dict[str, bytes]:
    return {p.relative_to(root).as_posix(): p.read_bytes() for p in sorted(root.rglob("*")) if p.is_file()}


def test_frames_do_not_depend_on_the_count_and_repeat_byte_for_byte(tmp_path):
    done = []
    write_dataset(tmp_path / "two", 2, seed=6, camera=CAM)
    two = _files(tmp_path / "two")
    three_names = write_dataset(tmp_path / "three", 3, seed=6, camera=CAM, progress=done.append)
    three = _files(tmp_path / "three")
    assert three_names == ["000000", "000001", "000002"] and done == [1, 2, 3]
    for folder in ("depth", "rgb", "instances"):
        for name in three_names[:2]:
            key = f"{folder}/{name}.png"
            assert two[key] == three[key], key
    assert two["cuboids/000001.json"] == three["cuboids/000001.json"]
    new = {"depth/000002.png", "rgb/000002.png", "instances/000002.png", "cuboids/000002.json"}
    assert set(three) - set(two) == new
    write_dataset(tmp_path / "again", 3, seed=6, camera=CAM)
    assert _files(tmp_path / "again") == three
    write_dataset(tmp_path / "other", 1, seed=7, camera=CAM)
    assert _files(tmp_path / "other")["depth/000000.png"] != three["depth/000000.png"]


def test_frame_i_is_generated_from_the_seed_pair(tmp_path):
    options = SceneOptions(clutter=(0, 1))
    write_dataset(tmp_path, 2, seed=21, camera=CAM, options=options)
    scene = generate_scene((21, 1), CAM, options)
    depth = cv2.imread(str(tmp_path / "depth" / "000001.png"), cv2.IMREAD_UNCHANGED)
    assert depth.dtype == np.uint16 and np.array_equal(depth, depth_to_png_units(scene.depth_m))
    rgb = cv2.imread(str(tmp_path / "rgb" / "000001.png"), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(rgb[..., ::-1], scene.rgb)  # PNG files hold BGR
    instances = cv2.imread(str(tmp_path / "instances" / "000001.png"), cv2.IMREAD_UNCHANGED)
    assert instances.dtype == np.uint16 and np.array_equal(instances, scene.instances)
    gt = json.loads((tmp_path / "cuboids" / "000001.json").read_text())
    assert gt["settings"] == {
        "generator": "cuboidcli.synth",
        "seed": [21, 1],
        "options": json.loads(json.dumps(options.to_dict())),
    }
    assert gt["input"] == {
        "depth": "depth/000001.png",
        "rgb": "rgb/000001.png",
        "instances": "instances/000001.png",
    }
    assert gt["objects"] == scene.objects and gt["room"] == json.loads(json.dumps(scene.room))
    assert np.allclose(gt["world_from_camera"], scene.world_from_camera, rtol=0, atol=0)
    synth = json.loads((tmp_path / "synth.json").read_text())
    assert synth == {
        "generator": "cuboidcli.synth",
        "seed": 21,
        "count": 2,
        "camera": json.loads(json.dumps(CAM.to_dict())),
        "options": json.loads(json.dumps(options.to_dict())),
        "split_rule": "index % 10: 0-7 train, 8 val, 9 test",
    }
    cameras = json.loads((tmp_path / "cameras.json").read_text())
    assert cameras == {n: {**CAM.to_dict(), "depth_scale": 0.001} for n in ("000000", "000001")}


def test_splits_follow_the_index(tmp_path, monkeypatch):
    # the split rule needs many frames; a stand-in scene keeps this fast (the names and splits are
    # written by write_dataset itself)
    from cuboidcli.synth import dataset as synth_dataset

    scene = generate_scene(0, CAM)
    monkeypatch.setattr(synth_dataset, "generate_scene", lambda seed, camera, options: scene)
    names = write_dataset(tmp_path, 23, seed=1, camera=CAM)
    splits = json.loads((tmp_path / "splits.json").read_text())
    assert splits["val"] == ["000008", "000018"] and splits["test"] == ["000009", "000019"]
    assert splits["train"] == [n for n in names if int(n) % 10 < 8] and len(splits["train"]) == 19


def test_bad_counts_and_workers_are_refused(tmp_path):
    with pytest.raises(ValueError, match=r"count must be at least 1 \(got 0\)"):
        write_dataset(tmp_path / "a", 0)
    with pytest.raises(ValueError, match=r"workers must be at least 1 \(got 0\)"):
        write_dataset(tmp_path / "b", 1, workers=0)
    assert not (tmp_path / "a").exists() and not (tmp_path / "b").exists()


def test_depth_png_units_round_to_millimetres_and_saturate():
    metres = np.array([0.0, 0.0004, 0.0006, 1.2346, 65.535, 70.0], np.float32)
    assert depth_to_png_units(metres).tolist() == [0, 0, 1, 1235, 65535, 65535]
    assert depth_to_png_units(metres, 0.0002)[3] == 6173
    assert depth_to_png_units(metres).dtype == np.uint16


def test_write_frame_and_scene_result_without_a_name(tmp_path):
    scene = generate_scene(2, CAM)
    bare = scene_result(scene)
    assert bare.input == {} and bare.settings == {"generator": "cuboidcli.synth", "seed": [2]}
    assert bare.cuboids is scene.cuboids and bare.camera == CAM
    write_frame(tmp_path, "x", scene)
    assert sorted(p.relative_to(tmp_path).as_posix() for p in tmp_path.rglob("*.*")) == [
        "cuboids/x.json",
        "depth/x.png",
        "instances/x.png",
        "rgb/x.png",
    ]

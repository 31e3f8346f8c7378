"""One camera type: the intrinsics readers return a Camera that carries where it came from and the depth
unit its source states, neither of which is compared or written."""

from __future__ import annotations

import json

import pytest

import cuboidcli as cb
from cuboidcli.camera import Camera
from cuboidcli.io.depth import InputError, check_inputs, intrinsics_for_size, parse_intrinsics


def test_a_preset_carries_its_depth_unit_and_source():
    cam = parse_intrinsics(None, "tum")
    assert type(cam) is Camera and cam == Camera.preset("tum")
    assert cam.depth_scale == 1.0 / 5000.0 and cam.source == "preset:tum" and cam.sized
    assert cam.to_dict() == {"fx": 525.0, "fy": 525.0, "cx": 319.5, "cy": 239.5, "width": 640, "height": 480}
    assert "source" not in repr(cam) and "depth_scale" not in repr(cam)


def test_given_intrinsics_without_a_size(tmp_path):
    cam = parse_intrinsics("500,501,320,240")
    assert (cam.width, cam.height, cam.depth_scale, cam.source) == (0, 0, None, "command line")
    assert not cam.sized
    f = tmp_path / "cam.json"
    f.write_text(json.dumps({"fx": 1, "fy": 2, "cx": 3, "cy": 4, "width": 8, "depth_scale": 0.0002}))
    cam = parse_intrinsics(str(f))
    assert cam == Camera(1.0, 2.0, 3.0, 4.0, 8, 0) and cam.depth_scale == 0.0002 and cam.source == str(f)
    assert not cam.sized  # a width without a height is no size


def test_provenance_is_no_part_of_the_pinhole():
    a = Camera(1.0, 2.0, 3.0, 4.0, 8, 6, 0.001, "here")
    b = Camera(1.0, 2.0, 3.0, 4.0, 8, 6)
    assert a == b and hash(a) == hash(b) and a.to_dict() == b.to_dict()
    assert a.with_size(16, 12).source == "here"  # the same intrinsics, for another size
    assert Camera.from_dict(a.to_dict()) == a


def test_a_preset_is_scaled_to_the_image_with_its_depth_unit():
    cam = intrinsics_for_size(parse_intrinsics(None, "nyu"), 1280, 960, preset="nyu")
    assert (cam.width, cam.height, cam.depth_scale) == (1280, 960, 0.001)
    assert cam.source == "preset:nyu scaled to 1280x960"
    assert cam == Camera.preset("nyu").scaled(2.0)
    with pytest.raises(InputError, match="--camera nyu is for 640x480 images"):
        intrinsics_for_size(parse_intrinsics(None, "nyu"), 1000, 480, preset="nyu")


def test_the_size_note_needs_a_known_size():
    import numpy as np

    depth = np.full((48, 64), 2.0, np.float32)
    assert check_inputs(depth, Camera(50.0, 50.0, 32.0, 24.0)) == []
    assert check_inputs(depth, Camera(50.0, 50.0, 32.0, 24.0, 64, 0)) == []
    notes = check_inputs(depth, Camera(50.0, 50.0, 32.0, 24.0, 640, 480))
    assert notes == ["intrinsics are for 640x480 but the depth map is 64x48; using them unscaled"]


def test_read_camera_sizes():
    assert cb.read_camera(preset="nyu", width=320).to_dict()["height"] == 480
    assert cb.read_camera("1,2,3,4", height=5) == Camera(1.0, 2.0, 3.0, 4.0, 0, 5)
    with pytest.raises(ValueError, match="give the intrinsics"):
        cb.read_camera()
    with pytest.raises(ValueError, match="the depth map is 64x48 but the camera is 640x480"):
        Camera.preset("nyu").for_image(64, 48)
    assert Camera(1.0, 2.0, 3.0, 4.0).for_image(64, 48) == Camera(1.0, 2.0, 3.0, 4.0, 64, 48)

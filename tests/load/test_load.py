"""cuboidcli.load: what an input is (source_of), the loading options that apply to it (LoadOptions,
refused_options, the ``load`` entry of a result's settings), and one Input for a frame and for a room.
Nothing is fitted here."""

from __future__ import annotations

import cv2
import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.io.depth import InputError
from cuboidcli.load import LoadOptions, load, refused_options, source_of
from cuboidcli.load.room import parse_up

CAM = Camera(60.0, 60.0, 39.5, 29.5)


def _cloud(n: int = 2000) -> np.ndarray:
    rng = np.random.default_rng(0)
    floor = np.c_[rng.uniform(0, 4, (n, 2)), np.zeros(n)]
    wall = np.c_[rng.uniform(0, 4, n), np.zeros(n), rng.uniform(0, 2.5, n)]
    return np.concatenate([floor, wall])


def test_what_an_input_is(tmp_path):
    depth = np.full((60, 80), 2.0, np.float32)
    assert source_of(depth, CAM) == "depth" and source_of(_cloud()) == "points"
    assert source_of(np.c_[_cloud(), np.zeros((4000, 3))]) == "points"  # points with colours
    with pytest.raises(InputError, match=r"shape \(60, 80\)"):
        source_of(depth)  # a depth map without its camera
    cv2.imwrite(str(tmp_path / "d.png"), np.full((60, 80), 2000, np.uint16))
    cv2.imwrite(str(tmp_path / "p.png"), np.full((60, 80, 3), 90, np.uint8))
    np.save(tmp_path / "room.npy", _cloud().astype(np.float32))
    assert source_of(tmp_path / "d.png") == "depth" and source_of(tmp_path / "p.png") == "photo"
    assert source_of(tmp_path / "room.npy") == "scan"
    (tmp_path / "frames").mkdir()
    with pytest.raises(InputError, match="not an RGB-D sequence"):
        source_of(tmp_path / "frames")
    with pytest.raises(InputError, match="not found"):
        source_of(tmp_path / "none.png")


def test_the_loading_options_that_apply_to_each_source():
    options = LoadOptions(intrinsics="1,1,0,0", camera="tum", depth_scale=0.002, unit="cm", every=3)
    assert options.to_dict("depth") == {"intrinsics": "1,1,0,0", "camera": "tum", "depth_scale": 0.002}
    assert options.to_dict("sequence") == {
        "intrinsics": "1,1,0,0", "camera": "tum", "depth_scale": 0.002, "every": 3,
    }  # fmt: skip
    assert options.to_dict("scan") == {"unit": "cm"} and options.to_dict("points") == {}
    assert LoadOptions().to_dict("photo") == {
        "intrinsics": None, "camera": None, "depth_scale": None, "depth_model": None,
    }  # fmt: skip
    # only options set to other than their default are refused
    assert refused_options(LoadOptions(), "points") == []
    assert refused_options(options, "scan") == ["intrinsics", "camera", "depth_scale", "every"]
    assert refused_options(options, "sequence") == ["unit"]
    assert refused_options(LoadOptions(every=2), "depth") == ["every"]


def test_an_option_that_does_not_apply_is_an_input_error():
    with pytest.raises(InputError, match="--every does not apply to points in memory; leave it out"):
        load(_cloud(), LoadOptions(every=2))
    with pytest.raises(InputError, match="--unit does not apply to a depth map"):
        load(np.full((60, 80), 2.0), LoadOptions(unit="cm"), camera=CAM)


def test_a_frame_and_a_room_as_one_input():
    frame = load(np.full((60, 80), 2.0), camera=CAM)
    assert frame.kind == "frame" and frame.frame == "opencv" and frame.source == "depth"
    assert frame.camera.width == 80 and frame.depth_m.dtype == np.float32 and frame.points is None
    assert frame.meta["depth_source"] == "array" and frame.views == []
    room = load(_cloud())
    assert room.kind == "room" and room.frame == "world" and room.source == "points"
    assert room.camera is None and room.depth_m is None and room.views == []
    assert np.array_equal(room.points, _cloud()) and room.meta["n_points"] == 4000


def test_up_is_named_or_given_as_a_vector():
    assert parse_up("y") == (0.0, 1.0, 0.0) and parse_up(None) is None
    assert parse_up("0,0,2") == (0.0, 0.0, 1.0) and parse_up(" -Y ") == (0.0, -1.0, 0.0)
    for bad in ("0,0,0", "up", "1,2"):
        with pytest.raises(InputError, match="--up"):
            parse_up(bad)

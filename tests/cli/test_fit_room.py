"""`cuboids fit ROOM`: a point cloud or a posed sequence folder, one world-frame result."""

from __future__ import annotations

import json
import struct
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from cuboidcli.cli.main import app
from cuboidcli.io.result import read_result
from tests.fitting.test_room_fit import scanned_room

runner = CliRunner()
SHARED = Path(__file__).resolve().parents[3] / "shared" / "data"


def run(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_a_point_cloud_gives_a_world_frame_result_and_its_outputs(tmp_path):
    src = tmp_path / "room.npy"
    np.save(src, scanned_room().astype(np.float32))
    out = tmp_path / "room.json"
    r = run("fit", src, "-o", out, "--voxel", "0.1", "--glb", "--ply", "-q")
    assert r.exit_code == 0, r.output
    d = json.loads(out.read_text())
    assert d["frame"] == "world" and d["camera"] is None
    assert d["settings"]["max_cuboids"] == 60 and d["settings"]["voxel_m"] == 0.1
    assert "scene" not in d["settings"] and d["settings"]["load"] == {"unit": "m"}
    kinds = [c["kind"] for c in d["cuboids"]]
    assert "floor" in kinds and kinds.count("wall") >= 3
    assert np.allclose(np.asarray(d["world_from_input"])[:3, :3] @ d["up"]["up"], [0, 0, 1], atol=1e-6)
    assert d["timing_s"]["total"] > 0 and "load" in d["timing_s"] and "objects" in d["timing_s"]
    # the cabinet as one whole object, made of object cuboids, standing on the floor
    (cabinet,) = [o for o in d["objects"] if o["cuboids"]]
    assert set(cabinet["cuboids"]) <= {i for i, k in enumerate(kinds) if k == "object"}
    # (0.6 x 1.0 x 1.2 m, its back 15 cm from the wall: within the shell's 1.9 voxels, 19 cm, its side faces'
    # points are the wall's, and its box starts where the clearance ends)
    assert sorted(round(2 * v, 1) for v in cabinet["half_size"]) == [0.6, 1.0, 1.3]
    assert abs(cabinet["center"][2] - cabinet["half_size"][2]) < 0.05
    res = read_result(out)  # the schema takes a world result without a camera
    assert res.frame == "world" and res.camera is None and len(res.cuboids) == len(kinds)
    for name in ("room.glb", "room_points.ply", "room_cuboids.ply"):
        assert (tmp_path / name).stat().st_size > 0
    import trimesh

    glb = trimesh.load(tmp_path / "room.glb")  # the cabinet's object: a translucent box beside the cuboids
    assert "whole_object_00" in glb.graph.nodes and len(glb.geometry) == len(kinds) + len(d["objects"])
    box = glb.geometry["whole_object_00"]
    assert cabinet["kind"] == "object"
    data = (tmp_path / "room.glb").read_bytes()
    (length,) = struct.unpack("<I", data[12:16])
    nodes = {n["name"]: n for n in json.loads(data[20 : 20 + length])["nodes"]}
    assert nodes["whole_object_00"]["extras"]["kind"] == "object"
    assert nodes["whole_object_00"]["extras"]["cuboids"] == cabinet["cuboids"]
    assert sorted(np.round(box.extents, 1)) == sorted(round(2 * v, 1) for v in cabinet["half_size"])


@pytest.mark.parametrize(
    "make, message",
    [
        (lambda p: np.save(p, np.random.rand(10, 3)), "at least 100"),
        (lambda p: np.save(p, np.random.rand(5000, 3) * 4000), "--unit mm"),
    ],
)
def test_bad_clouds_are_one_line_and_exit_2_with_nothing_written(tmp_path, make, message):
    src = tmp_path / "bad.npy"
    make(src)
    out = tmp_path / "bad.json"
    r = run("fit", src, "-o", out)
    assert r.exit_code == 2
    assert message in r.output and len(r.output.strip().splitlines()) == 1
    assert not out.exists()


def test_room_options_are_checked(tmp_path):
    src = tmp_path / "room.npy"
    np.save(src, scanned_room())
    assert "choose auto" in run("fit", src, "--visibility", "sideways").output
    assert "--up" in run("fit", src, "--up", "0,0,0").output
    assert run("fit", src, "--workers", "2").exit_code == 2


def test_a_synthetic_scan_sequence_is_fused_and_fitted(tmp_path):
    from cuboidcli.camera import Camera
    from cuboidcli.synth.scan import generate_room_scan, write_room_scan

    cam = Camera.preset("nyu").scaled(0.25)
    root = write_room_scan(tmp_path / "scan", generate_room_scan(3, views=4, camera=cam))
    out = tmp_path / "scan.json"
    r = run("fit", root, "-o", out, "--voxel", "0.1", "--overlay", "-q")
    assert r.exit_code == 0, r.output
    d = json.loads(out.read_text())
    assert d["frame"] == "world" and d["camera"]["width"] == cam.width
    assert d["fit_info"]["visibility"] == "views" and d["up"]["source"] == "estimated"
    assert np.allclose(d["up"]["up"], [0, 0, 1], atol=0.02)  # the synthetic world is z up
    names = {f["name"] for f in d["frames"]}
    assert len(names) == 4 and all(set(c["frames"]) <= names for c in d["cuboids"])
    assert any(c["frames"] for c in d["cuboids"])
    floors = [c for c in d["cuboids"] if c["kind"] == "floor"]
    assert floors and abs(floors[0]["center"][2]) < 0.1
    assert len(list(tmp_path.glob("scan_overlay_*.png"))) == 3


@pytest.mark.skipif(not (SHARED / "redwood").is_dir(), reason="needs ../shared/data")
def test_the_real_redwood_sequence(tmp_path):
    out = tmp_path / "rw.json"
    r = run("fit", SHARED / "redwood", "-o", out, "-q")
    assert r.exit_code == 0, r.output
    d = json.loads(out.read_text())
    kinds = [c["kind"] for c in d["cuboids"]]
    assert kinds.count("floor") == 1 and kinds.count("wall") >= 2
    assert np.allclose(d["up"]["up"], [0, 1, 0], atol=0.05)  # this trajectory's world is y up


def test_a_folder_of_rooms_runs_on_workers_and_resumes(tmp_path):
    rooms = tmp_path / "rooms"
    rooms.mkdir()
    np.save(rooms / "a.npy", scanned_room(0).astype(np.float32))
    np.save(rooms / "b.npy", scanned_room(1).astype(np.float32))
    out = tmp_path / "out"
    r = run("fit", rooms, "-o", out, "--voxel", "0.1", "--workers", "2", "--glb")
    assert r.exit_code == 0, r.output
    assert "2 done, 0 skipped, 0 failed" in r.output
    for name in ("a_cuboids.json", "b_cuboids.json", "a_cuboids.glb"):
        assert (out / name).is_file()
    assert json.loads((out / "a_cuboids.json").read_text())["frame"] == "world"
    again = run("fit", rooms, "-o", out, "--voxel", "0.1", "--glb")
    assert "0 done, 2 skipped" in again.output
    # a result written before a setting existed was fitted with its default: still complete
    saved = json.loads((out / "a_cuboids.json").read_text())
    del saved["settings"]["refine_iters"], saved["settings"]["virtual_view_m"]
    (out / "a_cuboids.json").write_text(json.dumps(saved))
    assert "0 done, 2 skipped" in run("fit", rooms, "-o", out, "--voxel", "0.1", "--glb").output
    other = run("fit", rooms, "-o", out, "--voxel", "0.12", "--glb")  # other settings: fitted again
    assert "2 done, 0 skipped" in other.output


def test_a_bare_scan_opens_in_the_viewer_and_the_simulators(tmp_path):
    pytest.importorskip("plotly")
    mujoco = pytest.importorskip("mujoco")
    src = tmp_path / "room.npy"
    np.save(src, scanned_room().astype(np.float32))
    out = tmp_path / "room.json"
    r = run("fit", src, "-o", out, "--voxel", "0.1", "--html", "--mjcf", "--urdf", "--usd", "-q")
    assert r.exit_code == 0, r.output
    page = (tmp_path / "room.html").read_text()
    assert "a room, in its own frame" in page and "points (" in page
    assert "1 object (dashed)" in page and "objects (1)" in page
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "room_mjcf.xml"))
    d = json.loads(out.read_text())
    assert model.ngeom == len(d["cuboids"]) and model.ncam == 0
    floor = next(i for i, c in enumerate(d["cuboids"]) if c["kind"] == "floor")
    # the MJCF is the levelled world: the floor's top lies at the input's z = 0 (this room is z up)
    geom = model.geom(f"floor_{floor:02d}")
    assert abs(geom.pos[2] + geom.size.min()) < 0.05
    assert (tmp_path / "room.urdf").is_file() and (tmp_path / "room.usda").is_file()

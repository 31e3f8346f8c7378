"""The room settings of ``cuboids fit`` reach a room (``--max-cuboids``, ``--voxel``, ``--up``,
``--visibility``), the loading options reach a sequence (``--every``, ``--camera``) and are recorded under
``settings.load``, an option that does not apply to the input is refused in one line (exit 2), and points
given in memory fit as the same points read from a file. On a small synthetic room: a box room with a
table, a few thousand points."""

from __future__ import annotations

import json
from pathlib import Path

import numpy as np
import pytest
from typer.testing import CliRunner

from cuboidcli.cli.main import app

#: A quick estimator: the tests are about where the options go, not about the cuboids.
QUICK = ("--hypotheses", "128", "--device", "cpu", "-q")

runner = CliRunner()


def run(*args):
    return runner.invoke(app, [str(a) for a in args])


def _plane(rng, origin, e1, e2, n: int) -> np.ndarray:
    uv = rng.uniform(0, 1, (n, 2))
    return np.asarray(origin) + uv[:, :1] * np.asarray(e1) + uv[:, 1:] * np.asarray(e2)


def _crate(rng, lo, size, per_m2: float = 600.0) -> np.ndarray:
    """Points on the faces of an upright box (corner ``lo``, ``size``), all but its bottom."""
    lo, (sx, sy, sz) = np.asarray(lo, dtype=np.float64), size
    faces = [
        (lo + [0, 0, sz], [sx, 0, 0], [0, sy, 0]),
        (lo, [sx, 0, 0], [0, 0, sz]),
        (lo + [0, sy, 0], [sx, 0, 0], [0, 0, sz]),
        (lo, [0, sy, 0], [0, 0, sz]),
        (lo + [sx, 0, 0], [0, sy, 0], [0, 0, sz]),
    ]
    counts = [int(per_m2 * np.linalg.norm(e1) * np.linalg.norm(e2)) + 20 for _, e1, e2 in faces]
    return np.concatenate([_plane(rng, o, e1, e2, n) for (o, e1, e2), n in zip(faces, counts, strict=True)])


#: Crates along the walls: (corner, size) in metres.
CRATES = [
    ((0.1, 0.1, 0.0), (0.4, 0.4, 0.5)),
    ((3.3, 0.1, 0.0), (0.5, 0.6, 0.4)),
    ((3.2, 2.3, 0.0), (0.6, 0.5, 0.8)),
    ((0.1, 2.4, 0.0), (0.5, 0.5, 0.3)),
    ((1.6, 0.1, 0.0), (0.8, 0.4, 0.6)),
    ((1.7, 2.5, 0.0), (0.6, 0.4, 1.0)),
]


def box_room(seed: int = 0) -> np.ndarray:
    """(N, 3) float64 points, z up, of a 4 x 3 x 2.5 m room's floor and four walls, a table (a 1.2 x 0.8 m
    top at 0.75 m on four legs) and six crates along the walls: more structures than 8 cuboids explain.
    Float32 values, so that a PLY of them holds the same points."""
    rng = np.random.default_rng(seed)
    parts = [
        _plane(rng, [0, 0, 0], [4, 0, 0], [0, 3, 0], 2000),
        _plane(rng, [0, 0, 0], [4, 0, 0], [0, 0, 2.5], 800),
        _plane(rng, [0, 3, 0], [4, 0, 0], [0, 0, 2.5], 800),
        _plane(rng, [0, 0, 0], [0, 3, 0], [0, 0, 2.5], 600),
        _plane(rng, [4, 0, 0], [0, 3, 0], [0, 0, 2.5], 600),
        _plane(rng, [1.4, 1.1, 0.75], [1.2, 0, 0], [0, 0.8, 0], 500),
    ]
    for x in (1.45, 2.5):
        for y in (1.15, 1.8):
            parts.append(_plane(rng, [x, y, 0], [0.05, 0, 0], [0, 0, 0.75], 60))
    parts += [_crate(rng, lo, size) for lo, size in CRATES]
    pts = np.concatenate(parts)
    hidden = np.zeros(len(pts), bool)  # the walls and floor behind and under the crates
    for lo, size in CRATES:
        hidden |= np.all((pts > np.asarray(lo) - 0.01) & (pts < np.asarray(lo) + size - 0.01), axis=1)
    pts = pts[~hidden]
    pts = pts + rng.normal(0, 0.003, pts.shape)
    return pts.astype(np.float32).astype(np.float64)


@pytest.fixture(scope="module")
def room(tmp_path_factory) -> Path:
    """The box room as a binary PLY (the project's writer)."""
    from cuboidcli.export.ply import write_point_ply

    pts = box_room()
    path = tmp_path_factory.mktemp("room") / "room.ply"
    return write_point_ply(path, pts, np.full((len(pts), 3), 128, np.uint8))


@pytest.fixture(scope="module")
def sequence(tmp_path_factory) -> Path:
    """A posed RGB-D sequence of 4 frames (80x60), as ``cuboids synth --views 4`` writes a room scan."""
    from cuboidcli.camera import Camera
    from cuboidcli.synth.scan import generate_room_scan, write_room_scan

    cam = Camera.preset("nyu").scaled(0.125)
    root = tmp_path_factory.mktemp("seq") / "scan"
    return write_room_scan(root, generate_room_scan(3, views=4, camera=cam))


@pytest.fixture()
def depth_png(tmp_path) -> Path:
    import cv2

    path = tmp_path / "d.png"
    cv2.imwrite(str(path), np.full((60, 80), 2000, np.uint16))
    return path


def _fit(tmp_path, src, *args) -> dict:
    out = tmp_path / "out.json"
    r = run("fit", src, "-o", out, *QUICK, *args)
    assert r.exit_code == 0, r.output
    return json.loads(out.read_text())


def test_max_cuboids_reaches_a_room(room, tmp_path):
    # the room has more structures than 8 cuboids explain: the bound is what stops the fit
    capped = _fit(tmp_path, room, "--max-cuboids", "8")
    assert capped["settings"]["max_cuboids"] == 8 and len(capped["cuboids"]) == 8
    assert capped["fit_info"]["stop_reason"] == "max_cuboids"
    default = _fit(tmp_path, room)
    assert default["settings"]["max_cuboids"] == 60 and 8 < len(default["cuboids"]) <= 60
    # a room's settings are flat, with how it was read
    assert "scene" not in default["settings"] and default["settings"]["load"] == {"unit": "m"}
    assert default["settings"]["voxel_m"] == 0.035 and default["settings"]["up"] is None


def test_voxel_up_and_visibility_reach_a_room(room, tmp_path):
    coarse = _fit(tmp_path, room, "--voxel", "0.05", "--max-cuboids", "2")
    assert coarse["settings"]["voxel_m"] == 0.05 and coarse["fit_info"]["voxel_m"] >= 0.05
    given = _fit(tmp_path, room, "--up", "y", "--max-cuboids", "2")
    assert given["settings"]["up"] == [0.0, 1.0, 0.0]
    assert given["up"]["source"] == "given" and np.allclose(given["up"]["up"], [0, 1, 0])
    plain = _fit(tmp_path, room, "--visibility", "plain", "--max-cuboids", "2")
    assert plain["settings"]["visibility"] == "plain" and plain["fit_info"]["visibility"] == "plain"
    # by default: the voxels asked for, the room's own up, views
    assert coarse["up"]["source"] == "estimated" and coarse["fit_info"]["visibility"] == "views"


def test_every_and_camera_reach_a_sequence(sequence, tmp_path):
    every = _fit(tmp_path, sequence, "--every", "2", "--camera", "tum", "--max-cuboids", "1")
    assert every["settings"]["load"]["every"] == 2 and every["settings"]["load"]["camera"] == "tum"
    assert every["input"]["frames_total"] == 2
    assert every["input"]["depth_scale"] == pytest.approx(1 / 5000)  # the preset's depth unit was read
    all_frames = _fit(tmp_path, sequence, "--max-cuboids", "1")
    assert all_frames["settings"]["load"]["every"] == 1 and all_frames["settings"]["load"]["camera"] is None
    assert all_frames["input"]["frames_total"] == 4 == 2 * every["input"]["frames_total"]
    assert all_frames["input"]["depth_scale"] == 0.001


@pytest.mark.parametrize(
    "args, message",
    [
        (("--depth", "DEPTH", "--voxel", "0.05"), "--voxel does not apply to a depth map"),
        (("ROOM", "--grid-step", "4"), "--grid-step does not apply to a room"),
        (("SEQUENCE", "--unit", "cm"), "--unit does not apply to a room"),
        (("--depth", "DEPTH", "--every", "2"), "--every does not apply to a depth map"),
        # typed at its default value, an option still has to apply to the input
        (("--depth", "DEPTH", "--voxel", "0.035"), "--voxel does not apply to a depth map"),
        (("--depth", "DEPTH", "--visibility", "auto"), "--visibility does not apply to a depth map"),
        (("--depth", "DEPTH", "--unit", "m"), "--unit does not apply to a depth map"),
        (("ROOM", "--every", "1"), "--every does not apply to a room"),
        (("--depth", "DEPTH", "--no-skip-existing"), "applies to a folder of inputs, not to one input"),
        # outputs the result cannot have are refused before the fit
        (("ROOM", "--overlay"), "--overlay draws a room's cuboids on its sequence's frames"),
        (("ROOM", "--rrd"), "--rrd is written for a depth map or a photo, not for a room"),
        (("ROOM", "--rerun"), "--rerun streams fitted frames, not a room"),
        (("--depth", "DEPTH", "--with-points"), "--with-points adds the points to the GLB: give --glb too"),
    ],
)
def test_an_option_that_does_not_apply_is_refused_in_one_line(
    room, sequence, depth_png, tmp_path, args, message
):
    inputs = {"DEPTH": depth_png, "ROOM": room, "SEQUENCE": sequence}
    out = tmp_path / "refused.json"
    r = run("fit", *(inputs.get(a, a) for a in args), "-o", out, "--device", "cpu")
    assert r.exit_code == 2, r.output
    assert message in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert not out.exists()


def test_points_in_memory_fit_as_the_same_points_in_a_ply(room):
    import cuboidcli as cb

    fitter = cb.Fitter(hypotheses=128, max_cuboids=6, device="cpu")
    from_array = fitter.fit(box_room())
    from_file = fitter.fit(room)
    assert from_array.kind == from_file.kind == "room" and from_array.record.frame == "world"
    assert len(from_array.cuboids) == len(from_file.cuboids) >= 3
    for a, b in zip(from_array.cuboids, from_file.cuboids, strict=True):
        assert np.array_equal(a.center, b.center) and np.array_equal(a.half_size, b.half_size)
        assert np.array_equal(a.rotation, b.rotation) and a.kind == b.kind
    assert from_array.settings["max_cuboids"] == 6 and from_array.input.source == "points"
    assert from_file.input.source == "scan"
    # an (N, 6) array carries colours, which do not change the fit
    colours = np.full((len(box_room()), 3), 200.0)
    coloured = fitter.fit(np.concatenate([box_room(), colours], axis=1))
    assert [c.center.tolist() for c in coloured.cuboids] == [c.center.tolist() for c in from_array.cuboids]
    o3d = pytest.importorskip("open3d")
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(box_room()))
    from_o3d = fitter.fit(cloud)
    assert [c.center.tolist() for c in from_o3d.cuboids] == [c.center.tolist() for c in from_array.cuboids]


def _linked_folder(tmp_path: Path, **rooms: Path) -> Path:
    """A folder of rooms: each room (a scan file or a sequence folder) linked under its given name."""
    folder = tmp_path / "rooms"
    folder.mkdir()
    for name, target in rooms.items():
        (folder / (name + target.suffix)).symlink_to(target, target_is_directory=target.is_dir())
    return folder


@pytest.mark.parametrize(
    ("kinds", "args", "message"),
    [
        (("scan",), ("-K", "500,500,320,240"), "-K does not apply to a room"),
        (("sequence",), ("--unit", "mm"), "--unit does not apply to a room"),
        (("scan", "sequence"), ("-K", "500,500,320,240"), "-K reads only the sequences of the folder"),
        (("scan", "sequence"), ("--unit", "mm"), "--unit reads only the scan files of the folder"),
    ],
)
def test_a_folder_of_rooms_refuses_an_option_its_rooms_do_not_read(
    room, sequence, tmp_path, kinds, args, message
):
    """Checked against the rooms the folder holds, before any is fitted: without it every scan of a folder
    given -K failed on its own (a line each, exit 1)."""
    folder = _linked_folder(tmp_path, **{k: {"scan": room, "sequence": sequence}[k] for k in kinds})
    out = tmp_path / "out"
    r = run("fit", folder, "-o", out, *args, *QUICK)
    assert r.exit_code == 2, r.output
    assert message in r.output and len(r.output.strip().splitlines()) == 1, r.output
    assert not out.exists()


def test_a_folder_of_sequences_records_their_loading_options(sequence, tmp_path):
    folder = _linked_folder(tmp_path, seq=sequence)
    out = tmp_path / "out"
    r = run("fit", folder, "-o", out, "--every", "2", "--max-cuboids", "4", *QUICK)
    assert r.exit_code == 0, r.output
    (result,) = out.glob("*_cuboids.json")
    settings = json.loads(result.read_text())["settings"]
    assert settings["load"]["every"] == 2 and settings["max_cuboids"] == 4

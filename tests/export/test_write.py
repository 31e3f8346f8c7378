"""cuboidcli.export.write: one writer, driven by the table of output kinds, for frames and rooms alike."""

from __future__ import annotations

import importlib.util
from dataclasses import dataclass
from pathlib import Path

import cv2
import numpy as np
import pytest

from cuboidcli import export
from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.export import OUTPUTS, FittedData, kinds_for, missing_extra, write, write_json_last
from cuboidcli.export.files import image_paths, output_files, output_paths, ply_paths
from cuboidcli.export.outputs import load_writer, overlay_views
from cuboidcli.io.result import FitResult, read_result

CAM = Camera(40.0, 40.0, 15.5, 11.5, 32, 24)
FRAME_KINDS = ("glb", "ply", "obj", "overlay", "html", "mjcf", "urdf", "usd", "rrd")
ROOM_KINDS = ("glb", "ply", "overlay", "html", "mjcf", "urdf", "usd")


def _installed(kinds) -> tuple[str, ...]:
    """The kinds whose optional library is installed here (the others are tested for their refusal)."""
    return tuple(kind for kind in kinds if missing_extra(kind) is None)


def _frame(*, depth: bool = True) -> FittedData:
    record = FitResult(CAM, [Cuboid([0.0, 0.0, 2.5], [0.5, 0.4, 0.3], np.eye(3))])
    depth_m = np.full((24, 32), 2.0, np.float32) if depth else None
    return FittedData.of_record(record, depth_m=depth_m)


@dataclass
class _View:
    name: str
    world_from_camera: np.ndarray
    depth_path: Path
    rgb_path: Path | None
    depth_scale: float = 0.001


def _room(folder: Path | None, n_views: int = 5, *, points: bool = True) -> FittedData:
    """A room of two boxes seen by ``n_views`` frames stepping back along -z (depth PNGs in ``folder``);
    no folder: a bare scan (no camera, no frames)."""
    boxes = [
        Cuboid([0.0, 0.0, 3.0], [0.5, 0.4, 0.3], np.eye(3), kind="floor"),
        Cuboid([0.4, -0.5, 3.0], [0.2, 0.2, 0.2], np.eye(3)),
    ]
    record = FitResult(None if folder is None else CAM, boxes, frame="world")
    views = []
    for i in range(n_views if folder is not None else 0):
        pose = np.eye(4)
        pose[2, 3] = -0.1 * i
        depth_path = folder / f"depth_{i:03d}.png"
        cv2.imwrite(str(depth_path), np.full((24, 32), 3000 + 100 * i, np.uint16))
        views.append(_View(f"{i:03d}", pose, depth_path, None))
    rng = np.random.default_rng(0)
    pts = rng.uniform([-1, -1, 2], [1, 1, 4], (200, 3)) if points else None
    labels = rng.integers(-2, 2, 200).astype(np.int32) if points else None
    whole = [Cuboid([0.2, -0.2, 3.0], [0.7, 0.6, 0.4], np.eye(3), extras={"cuboids": [0, 1]})]
    return FittedData(record, points=pts, point_labels=labels, objects=whole, up=np.array([0.0, -1.0, 0.0]),
                      views=views)  # fmt: skip


# ----------------------------------------------------------------------------------------- the table


def test_the_table_drives_the_listed_views():
    """The lists of kinds other modules read are the table's, and equal what they were when they were
    written out by hand."""
    assert list(OUTPUTS) == ["glb", "ply", "obj", "overlay", "html", "mjcf", "urdf", "usd", "rrd"]
    assert export.SCENES == {
        "html": (".html", "cuboidcli.export.html", "write_html"),
        "mjcf": ("_mjcf.xml", "cuboidcli.export.mjcf", "write_mjcf"),
        "urdf": (".urdf", "cuboidcli.export.mjcf", "write_urdf"),
        "usd": (".usda", "cuboidcli.export.usd", "write_usd"),
        "rrd": (".rrd", "cuboidcli.export.rerun", "write_rrd"),
    }
    assert dict(export.SCENE_EXTRAS) == {
        "html": ("plotly", "viz"),
        "mjcf": ("mujoco", "sim"),
        "urdf": None,
        "usd": ("pxr", "sim"),
        "rrd": ("rerun", "viz"),
    }
    assert export.WORLD_SCENES == ("html", "mjcf", "urdf", "usd", "rrd")
    assert export.EXTRAS == {kind: o.extra for kind, o in OUTPUTS.items()}
    for kind, o in OUTPUTS.items():
        assert callable(load_writer(kind)) and o.kind == kind and set(o.needs) <= set(o.frames)
    # the file names beside a result, and the old path helpers, come from the table's suffixes
    suffixes = [suffix for o in OUTPUTS.values() for _, suffix in o.files]
    assert [str(p).removeprefix("o/x") for p in output_paths("o/x", kinds=OUTPUTS).values()] == suffixes
    assert image_paths("d/a_overlay.jpg")["labels"] == Path("d/a_labels.png")  # the marker and the ending go
    assert image_paths("d/a.png")["panel"] == Path("d/a_panel.png")
    assert ply_paths("d/a_points.ply")["cuboids_ply"] == Path("d/a_cuboids.ply")


def test_a_patched_extra_is_what_the_check_sees(monkeypatch):
    """SCENE_EXTRAS is a view of the table's extras: patching it changes what write refuses."""
    monkeypatch.setitem(export.SCENE_EXTRAS, "urdf", ("no_such_robot_library", "sim"))
    assert export.EXTRAS["urdf"] == ("no_such_robot_library", "sim")
    assert missing_extra("urdf") == (
        "--urdf needs the optional extra: pip install 'cuboids[sim]' (no_such_robot_library is missing)"
    )
    with pytest.raises(KeyError):
        export.SCENE_EXTRAS["glb"] = None  # not a scene kind


# -------------------------------------------------------------------------------------------- frames


def test_write_of_a_frame_writes_exactly_the_named_files(tmp_path):
    kinds = _installed(FRAME_KINDS)
    assert {"glb", "ply", "obj", "overlay", "urdf"} <= set(kinds)
    written = write_json_last(_frame(), tmp_path / "x.json", kinds, with_points=True)
    named = output_files(tmp_path / "x.json", kinds)
    assert list(written.values()) == named  # in writing order, the JSON last
    assert list(written)[:4] == ["glb", "points_ply", "cuboids_ply", "obj"] and list(written)[-1] == "json"
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in named)
    assert read_result(written["json"]).cuboids[0].half_size.tolist() == [0.5, 0.4, 0.3]


def test_write_into_named_files(tmp_path):
    """``paths`` names a kind's main file elsewhere, its other files after it; a stem's ``.json`` is
    dropped; with no stem, only the named files are written (``cuboids export``)."""
    fitted = _frame()
    (tmp_path / "a").mkdir()
    written = write(fitted, tmp_path / "s", ["overlay"], paths={"ply": tmp_path / "a" / "p.ply"})
    assert written == {
        "points_ply": tmp_path / "a" / "p.ply",
        "cuboids_ply": tmp_path / "a" / "p_cuboids.ply",
        **output_paths(tmp_path / "s", ["overlay"]),
    }
    assert write(fitted, tmp_path / "b.json", ["obj"]) == {
        "obj": tmp_path / "b.obj",
        "mtl": tmp_path / "b.mtl",
    }
    record = FittedData.of_record(fitted.record)  # a saved result without its depth map
    assert write(record, None, (), paths={"glb": tmp_path / "c.glb"}) == {"glb": tmp_path / "c.glb"}
    with pytest.raises(ValueError, match="give the stem"):
        write(record, None, ["obj"])


# --------------------------------------------------------------------------------------------- rooms


def test_write_of_a_room_writes_exactly_the_named_files(tmp_path):
    (tmp_path / "seq").mkdir()
    room = _room(tmp_path / "seq")
    out = tmp_path / "out"
    out.mkdir()
    kinds = _installed(ROOM_KINDS)
    assert kinds_for(room, kinds) == (list(kinds), [])
    written = write(room, out / "r", kinds, with_points=True)
    views = [v.name for v in overlay_views(room.views)]
    assert views == ["000", "002", "004"]  # the first, the last and between
    expected = output_paths(out / "r", kinds=kinds, views=room.views)
    assert written == expected
    assert [k for k in written if k.startswith("overlay")] == [f"overlay_{v}" for v in views]
    assert sorted(p.name for p in out.iterdir()) == sorted(p.name for p in expected.values())
    # a frame whose depth is gone is passed over; the others are drawn
    (tmp_path / "seq" / "depth_002.png").unlink()
    again = write(room, out / "q", ["overlay"])
    assert list(again) == ["overlay_000", "overlay_004"]


def test_a_scan_leaves_its_overlays_out_and_says_why(tmp_path):
    scan = _room(None)
    todo, skipped = kinds_for(scan, ["overlay", "glb", "ply"])
    assert todo == ["glb", "ply"]
    assert skipped == ["overlay: left out, the room has no sequence frames to draw on (a scan has none)"]
    written = write(scan, tmp_path / "s", ["overlay", "glb", "ply"])
    assert list(written) == ["glb", "points_ply", "cuboids_ply"]
    assert sorted(p.name for p in tmp_path.iterdir()) == ["s.glb", "s_cuboids.ply", "s_points.ply"]


# ---------------------------------------------------------------------------------------- refusals


@pytest.mark.parametrize(
    ("case", "kinds", "with_points", "message"),
    [
        ("room", ["glb", "obj"], False, "obj: not written for a room's result, only for frames"),
        ("room", ["urdf", "rrd"], False, "rrd: not written for a room's result, only for frames"),
        ("room without points", ["glb", "ply"], False, "ply needs the room's input points"),
        ("room without points", ["glb"], True, "glb with points needs the room's input points"),
        ("frame without depth", ["glb", "obj", "ply"], False, "ply needs the depth map the result was"),
        ("frame without depth", ["obj", "glb"], True, "glb with points needs the depth map"),
        ("frame", ["glb", "stl"], False, "unknown output kind 'stl'; choose glb, ply, obj, overlay"),
        ("small depth", ["glb", "overlay"], False, "the depth map is 16x12 but the result's camera is 32x24"),
    ],
)
def test_an_output_that_does_not_apply_is_refused_before_anything_is_written(
    tmp_path, case, kinds, with_points, message
):
    fitted = {
        "room": lambda: _room(None),
        "room without points": lambda: _room(None, points=False),
        "frame without depth": lambda: _frame(depth=False),
        "frame": _frame,
        "small depth": lambda: FittedData.of_record(_frame().record, depth_m=np.ones((12, 16), np.float32)),
    }[case]()
    out = tmp_path / "out"
    out.mkdir()
    with pytest.raises(ValueError) as error:
        write_json_last(fitted, out / "x.json", kinds, with_points=with_points)
    assert str(error.value).startswith(message) and "\n" not in str(error.value)
    assert list(out.iterdir()) == []  # not even the outputs before it, nor the JSON


def test_a_missing_extra_is_one_line_naming_it_and_nothing_is_written(tmp_path, monkeypatch):
    real = importlib.util.find_spec
    gone = lambda name, *rest: None if name == "pxr" else real(name, *rest)  # noqa: E731
    monkeypatch.setattr(importlib.util, "find_spec", gone)
    line = "--usd needs the optional extra: pip install 'cuboids[sim]' (pxr is missing)"
    assert missing_extra("usd") == line
    assert missing_extra("urdf") is None and missing_extra("glb") is None
    for fitted in (_frame(), _room(None)):
        with pytest.raises(ImportError) as error:
            write_json_last(fitted, tmp_path / "x.json", ["glb", "ply", "urdf", "usd"])
        assert str(error.value) == line
        assert list(tmp_path.iterdir()) == []

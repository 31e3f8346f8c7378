"""cuboidcli.export.files: the names of the files `cuboids fit` writes, and that the writers use them."""

from __future__ import annotations

from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.export import FittedData, write
from cuboidcli.export.files import (
    output_files,
    output_paths,
    result_name,
    result_stem,
    results_folder,
)
from cuboidcli.io.result import FitResult


def test_result_names_of_inputs(tmp_path):
    assert result_name(tmp_path / "frame_depth.png") == "frame_depth_cuboids.json"
    assert result_name("room.v2.ply") == "room.v2_cuboids.json"
    seq = tmp_path / "scene.seq"
    seq.mkdir()
    assert result_name(seq) == "scene.seq_cuboids.json"  # a folder (a sequence) keeps its whole name
    assert results_folder(tmp_path / "frames") == Path("frames_cuboids")
    assert result_stem("out/a.json") == Path("out/a") and result_stem("out/a.b") == Path("out/a.b")


def test_output_paths_in_the_order_they_are_written():
    paths = output_paths("out/x", ("mjcf", "html", "overlay", "obj", "ply", "glb"))  # written in table order
    assert {k: str(p) for k, p in paths.items()} == {
        "glb": "out/x.glb",
        "points_ply": "out/x_points.ply",
        "cuboids_ply": "out/x_cuboids.ply",
        "obj": "out/x.obj",
        "mtl": "out/x.mtl",
        "overlay": "out/x_overlay.png",
        "labels": "out/x_labels.png",
        "labels_color": "out/x_labels_color.png",
        "panel": "out/x_panel.png",
        "html": "out/x.html",
        "mjcf": "out/x_mjcf.xml",
    }
    assert output_files("out/x.json", ["glb"]) == [
        Path("out/x.glb"),
        Path("out/x.json"),
    ]


def test_the_writer_writes_exactly_the_named_files(tmp_path):
    camera = Camera(40.0, 40.0, 15.5, 11.5, 32, 24)
    depth = np.full((24, 32), 2.0, np.float32)
    result = FitResult(camera, [Cuboid([0.0, 0.0, 2.5], [0.5, 0.4, 0.3], np.eye(3))])
    stem = tmp_path / "x"
    kinds = ("glb", "ply", "obj", "overlay")
    written = write(FittedData.of_record(result, depth_m=depth), f"{stem}.json", kinds)
    named = output_paths(stem, kinds)
    assert {k: Path(p) for k, p in written.items()} == named
    assert sorted(p.name for p in tmp_path.iterdir()) == sorted(p.name for p in named.values())

"""rerun recordings checked with rerun's own CLI: `rerun rrd verify` accepts them, and the Boxes3D they hold
are the JSON's boxes in the world frame, one row per frame on the `frame` timeline."""

from __future__ import annotations

import ast
import subprocess
from pathlib import Path

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.export.overlay import raycast
from cuboidcli.export.rerun import write_rrd, write_rrd_frames
from cuboidcli.export.scene import world_boxes
from cuboidcli.io.result import FitResult

pytest.importorskip("rerun")
CAM = Camera(60.0, 60.0, 31.5, 23.5, 64, 48)


def _frame(shift: float):
    boxes = [
        Cuboid([shift, 0.5, 2.0], [0.3, 0.2, 0.1], np.eye(3)),
        Cuboid([0.3, -0.2, 2.5], [0.2, 0.25, 0.15], np.eye(3), kind="wall"),
    ]
    depth = raycast(CAM, boxes).depth_m
    depth[~np.isfinite(depth)] = 0.0
    rgb = np.full((CAM.height, CAM.width, 3), 90, np.uint8)
    return FitResult(camera=CAM, cuboids=boxes), depth, rgb


def _box_rows(rerun_cli: str, path: Path) -> list[dict]:
    """The Boxes3D rows of a recording as `rerun rrd print -vvv` prints them."""
    printed = subprocess.run([rerun_cli, "rrd", "print", "-vvv", str(path)], capture_output=True, text=True)
    text = printed.stdout
    rows = []
    for line in text.splitlines():
        if "object_00" not in line:
            continue
        cells = [c.strip(" │") for c in line.split("┆")]
        rows.append(
            {
                "frame": int(cells[1]),
                "centers": np.array(ast.literal_eval(cells[3])),
                "half_sizes": np.array(ast.literal_eval(cells[5])),
                "labels": cells[6].strip("[]").split(", "),
            }
        )
    return rows


def test_a_recording_of_two_frames_holds_their_boxes_on_the_frame_timeline(tmp_path, rerun_cli):
    frames = [_frame(0.0), _frame(-0.4)]
    path = write_rrd_frames(frames, tmp_path / "two.rrd")
    check = subprocess.run([rerun_cli, "rrd", "verify", str(path)], capture_output=True, text=True)
    assert check.returncode == 0, check.stderr
    rows = sorted(_box_rows(rerun_cli, path), key=lambda r: r["frame"])
    assert [r["frame"] for r in rows] == [0, 1]
    for row, (result, _, _) in zip(rows, frames, strict=True):
        want = world_boxes(result)
        assert row["labels"] == ["object_00", "wall_01"]
        np.testing.assert_allclose(row["centers"], [b[1] for b in want], atol=1e-5)
        np.testing.assert_allclose(row["half_sizes"], [b[2] for b in want], atol=1e-6)
    assert not list(tmp_path.glob(".*"))  # no temporary file left


def test_one_result_without_inputs_is_a_valid_recording(tmp_path, rerun_cli):
    result, _, _ = _frame(0.0)
    path = write_rrd(result, tmp_path / "one.rrd")
    assert subprocess.run([rerun_cli, "rrd", "verify", str(path)], capture_output=True).returncode == 0
    assert [r["frame"] for r in _box_rows(rerun_cli, path)] == [0]

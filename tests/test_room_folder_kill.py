"""A folder of rooms killed mid-way (SIGINT, then SIGKILL) leaves only complete results, and the same
command run again fits the rest: a room's JSON is written last and atomically, as a frame's."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from pathlib import Path

import numpy as np

from tests.test_room_options import box_room

#: Quick settings: the test is about what a kill leaves, not about the cuboids.
QUICK = ["--hypotheses", "128", "--voxel", "0.08", "--device", "cpu", "-q", "--glb"]
#: Rooms in the folder: enough that a test process starved by a loaded machine still sees the run before
#: it has fitted them all (with 4, a run under a second test suite once finished before the kill).
ROOMS = 6


def _cuboids(*args, **kwargs) -> subprocess.Popen:
    env = {**os.environ, "OMP_NUM_THREADS": "1", "NUMBA_NUM_THREADS": "1"}
    command = [sys.executable, "-c", "from cuboidcli.cli.main import run; run()", "fit", *map(str, args)]
    return subprocess.Popen(command, env=env, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, **kwargs)


def _complete(out: Path) -> list[str]:
    """The rooms whose results are complete: a valid "cuboids/1" JSON with its GLB beside it."""
    done = []
    for path in sorted(out.glob("*_cuboids.json")):
        doc = json.loads(path.read_text())  # a partial JSON would raise here
        assert doc["schema"] == "cuboids/1" and doc["frame"] == "world"
        assert path.with_suffix(".glb").is_file(), f"{path.name} without its GLB"
        done.append(path.name)
    return done


def test_a_killed_folder_of_rooms_leaves_complete_results_and_resumes(tmp_path):
    from cuboidcli.export.ply import write_point_ply

    rooms = tmp_path / "rooms"
    rooms.mkdir()
    for i in range(ROOMS):
        pts = box_room(seed=i)
        write_point_ply(rooms / f"room_{i}.ply", pts, np.full((len(pts), 3), 128, np.uint8))
    out = tmp_path / "out"
    proc = _cuboids(rooms, "-o", out, *QUICK)
    deadline = time.monotonic() + 240
    while not list(out.glob("*_cuboids.json")) and time.monotonic() < deadline and proc.poll() is None:
        time.sleep(0.2)
    assert proc.poll() is None, "the run ended before it could be interrupted"
    proc.send_signal(signal.SIGINT)
    time.sleep(0.5)
    proc.kill()
    proc.wait(timeout=60)
    first = _complete(out)
    assert 1 <= len(first) < ROOMS
    stamps = {name: (out / name).stat().st_mtime_ns for name in first}

    again = _cuboids(rooms, "-o", out, *QUICK)
    output = again.communicate(timeout=600)[0].decode()
    assert again.returncode == 0, output
    assert _complete(out) == [f"room_{i}_cuboids.json" for i in range(ROOMS)]
    # the rooms fitted before the kill were kept, not fitted again
    assert {name: (out / name).stat().st_mtime_ns for name in first} == stamps

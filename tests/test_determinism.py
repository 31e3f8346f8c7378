"""The same seed gives the same cuboids whatever the thread counts, at the default settings, for a frame
and for a room: ``cuboids fit`` runs in fresh processes with OpenMP, numba and torch on 1 and on 2
threads (each reads its count from the environment when it starts), and their JSON results hold the same
cuboids, every number equal."""

from __future__ import annotations

import json
import os
import subprocess
import sys
from pathlib import Path

import cv2
import numpy as np

from tests.fitting.test_room_fit import scanned_room

ROOT = Path(__file__).resolve().parents[1]
SAMPLE = ROOT / "cuboidcli" / "data" / "sample"
#: The thread counts a run is repeated with; the pool sizes the libraries read at start-up.
THREADS = (1, 2)
THREAD_VARIABLES = ("OMP_NUM_THREADS", "NUMBA_NUM_THREADS", "MKL_NUM_THREADS", "OPENBLAS_NUM_THREADS")


def _fit(args: list[str], out: Path, threads: int) -> list[dict]:
    """``cuboids fit ARGS -o OUT --seed 11`` in a process whose libraries use ``threads`` threads: the
    cuboids of its result."""
    env = {**os.environ, **dict.fromkeys(THREAD_VARIABLES, str(threads))}
    cmd = [sys.executable, "-m", "cuboidcli.cli.main", "fit", *args, "--seed", "11", "-q", "-o", str(out)]
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=300, env=env, cwd=ROOT)
    assert proc.returncode == 0, proc.stderr
    record = json.loads(out.read_text())
    assert record["settings"]["hypotheses"] == 3072  # the default, not a reduced test setting
    return record["cuboids"]


def _same_for_every_thread_count(args: list[str], tmp_path: Path, at_least: int) -> None:
    runs = [_fit(args, tmp_path / f"threads{n}.json", n) for n in THREADS]
    assert len(runs[0]) >= at_least
    for other in runs[1:]:
        assert other == runs[0]  # every centre, half size, rotation and gain, equal to the last bit


def test_a_frame_fits_the_same_on_1_and_2_threads(tmp_path, room_depth):
    depth, _ = room_depth
    png = tmp_path / "frame.png"
    cv2.imwrite(str(png), np.round(depth * 1000).astype(np.uint16))
    _same_for_every_thread_count(["--depth", str(png), "--camera", "nyu"], tmp_path, at_least=4)


def test_a_room_fits_the_same_on_1_and_2_threads(tmp_path):
    points = tmp_path / "room.npy"
    np.save(points, scanned_room())  # a 4 x 3 m room with a cabinet, 30,000 points
    _same_for_every_thread_count([str(points)], tmp_path, at_least=5)

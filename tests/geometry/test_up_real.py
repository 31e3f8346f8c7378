"""The up direction of real ScanNet scans written in other conventions (../shared/data/scannet): a PLY is read
z up, and a scan written y up or x up must still come out floor-down. scene0004_00 (a long room with low
walls, a wall scoring above the floor) and scene0003_02 turned x up were fitted on their side before a floor
open above could win over the convention (:data:`cuboidcli.geometry.cloud.OPEN_FLOOR`)."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.evaluation.scannet import read_truth
from cuboidcli.geometry.cloud import estimate_normals, room_up, voxel_groups
from tests.conftest import SHARED_DATA

SCANNET = SHARED_DATA / "scannet"
TURNS = {
    "y up": np.array([[1.0, 0, 0], [0, 0, 1], [0, -1, 0]]),  # z -> y
    "y down": np.array([[1.0, 0, 0], [0, 0, -1], [0, 1, 0]]),
    "x up": np.array([[0, 0, 1.0], [0, 1, 0], [-1, 0, 0]]),
}


@pytest.mark.skipif(not (SCANNET / "scene0004_00_bbox.npy").is_file(), reason="no shared ScanNet scans")
@pytest.mark.parametrize("name", ["scene0004_00", "scene0003_02"])
@pytest.mark.parametrize("turn", list(TURNS))
def test_a_real_scan_written_in_another_convention_keeps_its_floor(name, turn):
    truth = read_truth(SCANNET, name)
    means = voxel_groups(truth.points @ TURNS[turn].T, 0.035)[0]
    up = room_up(means, estimate_normals(means, 0.105), hint=np.array([0.0, 0.0, 1.0]))
    assert up.source == "estimated"
    assert float(up.up @ (TURNS[turn] @ truth.up)) > np.cos(np.deg2rad(3.0))

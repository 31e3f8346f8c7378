"""USD stages read back with usd-core's own pxr: z up, metres, one Cube per cuboid at the JSON's place."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.export.scene import world_boxes
from cuboidcli.export.usd import write_usd
from cuboidcli.geometry.gravity import given_gravity
from cuboidcli.io.result import FitResult

pxr = pytest.importorskip("pxr")
from pxr import Usd, UsdGeom  # noqa: E402

CAM = Camera(500.0, 510.0, 319.5, 239.5, 640, 480)
SIGNS = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], dtype=float)


def _result() -> FitResult:
    turn = np.array([[0.8, 0.0, 0.6], [0.0, 1.0, 0.0], [-0.6, 0.0, 0.8]])
    boxes = [
        Cuboid([0.0, 1.4, 3.0], [2.0, 0.02, 2.0], np.eye(3), kind="floor"),
        Cuboid([-0.4, 1.0, 2.5], [0.25, 0.4, 0.2], turn),
    ]
    pose = given_gravity((0.0, 0.95, 0.2)).world_from_camera()
    return FitResult(camera=CAM, cuboids=boxes, extras={"world_from_camera": pose.tolist()})


@pytest.mark.parametrize("suffix", [".usda", ".usdc"])
def test_the_stage_holds_each_box_where_the_json_puts_it(tmp_path, suffix):
    result = _result()
    path = write_usd(result, tmp_path / f"room{suffix}")
    stage = Usd.Stage.Open(str(path))
    assert UsdGeom.GetStageUpAxis(stage) == UsdGeom.Tokens.z and UsdGeom.GetStageMetersPerUnit(stage) == 1.0
    cubes = [p for p in stage.Traverse() if p.IsA(UsdGeom.Cube)]
    assert [p.GetParent().GetName() for p in cubes] == ["floor_00", "object_01"]
    cache = UsdGeom.XformCache(0)
    for prim, (_, center, half, rot, _) in zip(cubes, world_boxes(result), strict=True):
        m = np.array(cache.GetLocalToWorldTransform(prim)).reshape(4, 4)
        size = UsdGeom.Cube(prim).GetSizeAttr().Get()
        corners = np.c_[SIGNS * size / 2, np.ones(8)] @ m  # USD: row vectors times the matrix
        want = center + (SIGNS * half) @ rot.T
        assert np.abs(corners[:, :3] - want).max() < 1e-3
    camera = UsdGeom.Camera(stage.GetPrimAtPath("/World/input_camera"))
    focal = camera.GetFocalLengthAttr().Get()
    assert focal / camera.GetHorizontalApertureAttr().Get() == pytest.approx(CAM.fx / CAM.width)
    # the camera looks along its -z: in the world that is the OpenCV camera's optical axis
    view = np.array(cache.GetLocalToWorldTransform(camera.GetPrim())).reshape(4, 4)
    pose = np.asarray(result.extras["world_from_camera"])
    assert np.allclose(-view[2, :3], pose[:3, :3] @ [0.0, 0.0, 1.0], atol=1e-6)


def test_empty_results_bad_endings_and_flat_boxes(tmp_path):
    empty = FitResult(camera=CAM, cuboids=[])
    stage = Usd.Stage.Open(str(write_usd(empty, tmp_path / "e.usda")))
    assert not [p for p in stage.Traverse() if p.IsA(UsdGeom.Cube)]
    with pytest.raises(ValueError, match="a USD stage is written to"):
        write_usd(empty, tmp_path / "e.obj")
    flat = FitResult(camera=CAM, cuboids=[Cuboid([0, 0, 2], [0.2, 0.0, 0.3], np.eye(3))])
    with pytest.raises(ValueError, match="object_00 has size"):
        write_usd(flat, tmp_path / "f.usda")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["e.usda"]  # nothing half-written is left

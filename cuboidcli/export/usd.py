"""USD stages from a result (usd-core's ``pxr``): opens in Isaac Sim, Blender, Houdini and usdview.

The stage is z-up with metersPerUnit 1, in the world frame of :mod:`cuboidcli.export.scene`: ``/World``
holds an Xform per cuboid (named by its scene name) whose transform places a ``Cube`` child of size 2
(-1..1) scaled by the half-sizes, and the input camera as a ``Camera`` prim.
"""

from __future__ import annotations

import os
from pathlib import Path

import numpy as np

from cuboidcli.export.mjcf import OPENCV_TO_GL_CAMERA, SIM_EXTRA_HINT
from cuboidcli.export.scene import camera_pose_world, world_boxes
from cuboidcli.io.result import FitResult

#: File endings a stage is written to: text (.usda), binary (.usdc) or either (.usd, binary).
USD_SUFFIXES = (".usda", ".usdc", ".usd")
#: Horizontal film width (mm) of the camera prim: its focal length follows from fx / image width.
FILM_WIDTH_MM = 36.0


def _pxr():
    try:
        from pxr import Gf, Usd, UsdGeom
    except ImportError:
        raise ImportError(f"USD stages need the optional extra: {SIM_EXTRA_HINT}") from None
    return Gf, Usd, UsdGeom


def _matrix(rotation: np.ndarray, translation: np.ndarray):
    """Gf.Matrix4d of a rigid transform; USD multiplies row vectors, so the rotation goes in transposed."""
    gf, _, _ = _pxr()
    m = np.eye(4)
    m[:3, :3] = np.asarray(rotation, dtype=np.float64).T
    m[3, :3] = translation
    return gf.Matrix4d(*(float(v) for v in m.reshape(16)))


def build_stage(result: FitResult, path: str):
    """A new stage at ``path`` holding the result (not yet saved)."""
    gf, usd, usd_geom = _pxr()
    boxes = world_boxes(result)  # refuses zero-size cuboids before anything is created
    stage = usd.Stage.CreateNew(path)
    usd_geom.SetStageUpAxis(stage, usd_geom.Tokens.z)
    usd_geom.SetStageMetersPerUnit(stage, 1.0)
    world = usd_geom.Xform.Define(stage, "/World")
    stage.SetDefaultPrim(world.GetPrim())
    for name, center, half, rot, rgba in boxes:
        xform = usd_geom.Xform.Define(stage, f"/World/{name}")
        xform.AddTransformOp().Set(_matrix(rot, center))
        cube = usd_geom.Cube.Define(stage, f"/World/{name}/box")
        cube.GetSizeAttr().Set(2.0)
        cube.AddScaleOp().Set(gf.Vec3d(*(float(v) for v in half)))
        cube.GetDisplayColorAttr().Set([gf.Vec3f(*(v / 255.0 for v in rgba[:3]))])
    if result.frame == "world":  # a room's result: no single camera to place
        return stage
    cam = result.camera
    pose = camera_pose_world(result)
    camera = usd_geom.Camera.Define(stage, "/World/input_camera")
    camera.AddTransformOp().Set(_matrix(pose[:3, :3] @ OPENCV_TO_GL_CAMERA, pose[:3, 3]))
    if cam.width and cam.height:
        focal = cam.fx * FILM_WIDTH_MM / cam.width
        camera.GetFocalLengthAttr().Set(float(focal))
        camera.GetHorizontalApertureAttr().Set(FILM_WIDTH_MM)
        camera.GetVerticalApertureAttr().Set(float(cam.height * focal / cam.fy))
    camera.GetClippingRangeAttr().Set(gf.Vec2f(0.01, 1000.0))
    return stage


def write_usd(
    result: FitResult, path: str | os.PathLike, *, depth_m=None, rgb=None, points=None, point_colors=None
) -> Path:
    """The USD stage of ``result`` at ``path`` (.usda, .usdc or .usd), written to a temporary file beside
    it and moved into place (the input images and points unused). ImportError naming the extra without
    usd-core; ValueError for another ending or a zero-size cuboid."""
    path = Path(path)
    if path.suffix.lower() not in USD_SUFFIXES:
        raise ValueError(f"a USD stage is written to {', '.join(USD_SUFFIXES)}, not {path.name}")
    tmp = path.with_name(f".{path.stem}.tmp{os.getpid()}{path.suffix}")
    try:
        stage = build_stage(result, str(tmp))
        stage.Save()
        del stage  # release the layer before the file moves
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path

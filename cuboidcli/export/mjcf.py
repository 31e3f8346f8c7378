"""MuJoCo scenes (MJCF) and URDF from a result: one static box per cuboid in the z-up world frame of
:mod:`cuboidcli.export.scene`, the input camera, metres.

The MJCF is built with MuJoCo's own ``MjSpec`` (compiled once to check it) and written with ``to_xml``;
the URDF is plain XML: a ``world`` link and one link per cuboid on a fixed joint, which MuJoCo, PyBullet,
Isaac Sim and ROS tools load.
"""

from __future__ import annotations

import math
import os
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

from cuboidcli.export.scene import camera_pose_world, world_boxes
from cuboidcli.io.atomic import atomic_write_text
from cuboidcli.io.result import FitResult

SIM_EXTRA_HINT = "pip install 'cuboids[sim]'"
#: MuJoCo and USD cameras look along their -z with +y up; OpenCV cameras along +z with +y down.
OPENCV_TO_GL_CAMERA = np.diag([1.0, -1.0, -1.0])


def _mujoco():
    try:
        import mujoco
    except ImportError:
        raise ImportError(f"MuJoCo scenes need the optional extra: {SIM_EXTRA_HINT}") from None
    return mujoco


def _quat_wxyz(rotation: np.ndarray) -> np.ndarray:
    mujoco = _mujoco()
    q = np.zeros(4)
    mujoco.mju_mat2Quat(q, np.ascontiguousarray(rotation, dtype=np.float64).reshape(9))
    return q


def scene_spec(result: FitResult):
    """A ``mujoco.MjSpec`` of the result: gravity -z, one static box geom per cuboid (collision and
    visual, the overlays' colour, named by the scene name), the input camera as ``input_camera``."""
    mujoco = _mujoco()
    spec = mujoco.MjSpec()
    spec.modelname = "cuboids"
    spec.option.gravity = [0.0, 0.0, -9.81]
    for name, center, half, rot, rgba in world_boxes(result):
        spec.worldbody.add_geom(
            name=name,
            type=mujoco.mjtGeom.mjGEOM_BOX,
            size=[float(v) for v in half],
            pos=[float(v) for v in center],
            quat=[float(v) for v in _quat_wxyz(rot)],
            rgba=[v / 255.0 for v in rgba],
        )
    if result.frame == "world":  # a room's result: no single camera to place
        return spec
    pose = camera_pose_world(result)
    cam = result.camera
    fovy = math.degrees(2.0 * math.atan(cam.height / (2.0 * cam.fy))) if cam.height else 45.0
    spec.worldbody.add_camera(
        name="input_camera",
        pos=[float(v) for v in pose[:3, 3]],
        quat=[float(v) for v in _quat_wxyz(pose[:3, :3] @ OPENCV_TO_GL_CAMERA)],
        fovy=fovy,
    )
    return spec


def write_mjcf(
    result: FitResult, path: str | os.PathLike, *, depth_m=None, rgb=None, points=None, point_colors=None
) -> Path:
    """The MuJoCo scene of ``result`` as MJCF XML, atomically (the input images and points are not used:
    a simulator scene holds the boxes). The spec is compiled first, so a file that MuJoCo would refuse is
    never written. ImportError naming the extra without MuJoCo; ValueError for a zero-size cuboid."""
    spec = scene_spec(result)
    spec.compile()
    return atomic_write_text(path, spec.to_xml())


def rpy(rotation: np.ndarray) -> tuple[float, float, float]:
    """URDF roll, pitch, yaw (rad) of a rotation: R = Rz(yaw) @ Ry(pitch) @ Rx(roll)."""
    r = np.asarray(rotation, dtype=np.float64)
    pitch = math.atan2(-r[2, 0], math.hypot(r[0, 0], r[1, 0]))
    if math.hypot(r[0, 0], r[1, 0]) < 1e-9:  # pitch +-90 degrees: roll and yaw share one axis
        return math.atan2(-r[1, 2], r[1, 1]), pitch, 0.0
    return math.atan2(r[2, 1], r[2, 2]), pitch, math.atan2(r[1, 0], r[0, 0])


def _origin(parent: ET.Element, xyz, rot) -> None:
    ET.SubElement(
        parent,
        "origin",
        xyz=" ".join(f"{v:.9g}" for v in xyz),
        rpy=" ".join(f"{v:.9g}" for v in rpy(rot)),
    )


def urdf_text(result: FitResult) -> str:
    """The URDF document of ``result``: link ``world``, one link per cuboid (box visual and collision of its
    full size, material of its colour) on a fixed joint ``<name>_joint`` to the world."""
    robot = ET.Element("robot", name="cuboids")
    ET.SubElement(robot, "link", name="world")
    for name, center, half, rot, rgba in world_boxes(result):
        link = ET.SubElement(robot, "link", name=name)
        size = " ".join(f"{2.0 * v:.9g}" for v in half)
        for part in ("visual", "collision"):
            el = ET.SubElement(link, part)
            _origin(el, (0.0, 0.0, 0.0), np.eye(3))
            ET.SubElement(ET.SubElement(el, "geometry"), "box", size=size)
            if part == "visual":
                material = ET.SubElement(el, "material", name=f"{name}_colour")
                ET.SubElement(material, "color", rgba=" ".join(f"{v / 255.0:.4g}" for v in rgba))
        joint = ET.SubElement(robot, "joint", name=f"{name}_joint", type="fixed")
        ET.SubElement(joint, "parent", link="world")
        ET.SubElement(joint, "child", link=name)
        _origin(joint, center, rot)
    ET.indent(robot)
    return '<?xml version="1.0"?>\n' + ET.tostring(robot, encoding="unicode") + "\n"


def write_urdf(
    result: FitResult, path: str | os.PathLike, *, depth_m=None, rgb=None, points=None, point_colors=None
) -> Path:
    """The URDF of ``result``, atomically (the input images and points unused). ValueError for a
    zero-size cuboid."""
    return atomic_write_text(path, urdf_text(result))

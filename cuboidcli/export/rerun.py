"""rerun recordings of results (rerun-sdk): the image, the depth map, the coloured points, the boxes and
the camera, in the z-up world frame of :mod:`cuboidcli.export.scene`; several frames on a ``frame``
timeline. Saved to an ``.rrd`` file (``cuboids export --rrd``, ``cuboids fit --rrd``) or streamed to a
running viewer (``cuboids fit --rerun``).
"""

from __future__ import annotations

import os
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from cuboidcli.export.scene import camera_pose_world, world_boxes
from cuboidcli.io.result import FitResult

VIZ_EXTRA_HINT = "pip install 'cuboids[viz]'"
#: Where a rerun viewer started with `rerun` listens.
DEFAULT_VIEWER = "rerun+http://127.0.0.1:9876/proxy"
#: Points logged per frame at most (the depth map is subsampled to stay within it).
MAX_RERUN_POINTS = 300_000


def _rerun():
    try:
        import rerun
    except ImportError:
        raise ImportError(f"rerun recordings need the optional extra: {VIZ_EXTRA_HINT}") from None
    return rerun


def log_result(rec, result: FitResult, depth_m: np.ndarray | None = None, rgb: np.ndarray | None = None):
    """Log one result to the recording stream ``rec`` at its current time: ``world/cuboids`` (Boxes3D with
    centres, half-sizes, quaternions, scene names as labels, the overlays' colours), ``world/camera`` (its
    pose and pinhole; the image and depth map under it) and ``world/points`` (coloured from the image)."""
    rr = _rerun()
    boxes = world_boxes(result)
    quats = []
    for _, _, _, rot, _ in boxes:
        from cuboidcli.cuboid import Cuboid

        w, x, y, z = Cuboid(np.zeros(3), np.ones(3), rot).quat_wxyz
        quats.append(rr.Quaternion(xyzw=[x, y, z, w]))
    rec.log(
        "world/cuboids",
        rr.Boxes3D(
            centers=[b[1] for b in boxes],
            half_sizes=[b[2] for b in boxes],
            quaternions=quats,
            labels=[b[0] for b in boxes],
            colors=[b[4] for b in boxes],
        ),
    )
    pose = camera_pose_world(result)
    cam = result.camera
    rec.log("world/camera", rr.Transform3D(translation=pose[:3, 3], mat3x3=pose[:3, :3]))
    rec.log(
        "world/camera/image",
        rr.Pinhole(
            image_from_camera=cam.K, width=cam.width, height=cam.height, camera_xyz=rr.ViewCoordinates.RDF
        ),
    )
    if rgb is not None:
        rec.log("world/camera/image/rgb", rr.Image(np.asarray(rgb, dtype=np.uint8)))
    if depth_m is not None:
        from cuboidcli.export.ply import depth_points

        rec.log("world/camera/image/depth", rr.DepthImage(np.asarray(depth_m, dtype=np.float32), meter=1.0))
        h, w = depth_m.shape
        step = 1
        while -(-h // step) * -(-w // step) > MAX_RERUN_POINTS:
            step += 1
        points, pix = depth_points(depth_m, cam, step)
        colors = None if rgb is None else np.asarray(rgb, dtype=np.uint8).reshape(-1, 3)[pix]
        world = points @ pose[:3, :3].T + pose[:3, 3]
        rec.log("world/points", rr.Points3D(world, colors=colors, radii=0.005))


def saved_inputs(result: FitResult) -> tuple[np.ndarray | None, np.ndarray | None]:
    """(depth map, image) a saved result was fitted on, read from the files its ``input`` records when they
    still exist and match its camera (depth estimated from a photo is not saved: None)."""
    from cuboidcli.io.depth import InputError, read_depth
    from cuboidcli.io.photo import read_photo

    cam, record = result.camera, result.input or {}
    depth = rgb = None
    try:
        if isinstance(record.get("depth"), str) and Path(record["depth"]).is_file():
            depth = read_depth(record["depth"], float(record.get("depth_scale") or 0.001))
        if isinstance(record.get("image"), str) and Path(record["image"]).is_file():
            rgb = read_photo(record["image"]).rgb
    except InputError:
        return None, None
    if depth is not None and depth.shape != (cam.height, cam.width):
        depth = None
    if rgb is not None and rgb.shape[:2] != (cam.height, cam.width):
        rgb = None
    return depth, rgb


def _recording(application: str = "cuboids"):
    rr = _rerun()
    rec = rr.RecordingStream(application)
    rec.log("world", rr.ViewCoordinates.RIGHT_HAND_Z_UP, static=True)
    return rec


def write_rrd_frames(frames: Iterable[tuple], path: str | os.PathLike) -> Path:
    """One recording of several frames, each ``(result, depth_m or None, rgb or None)``, at times 0, 1, ...
    of the ``frame`` timeline, saved to ``path`` (written beside it and moved into place)."""
    path = Path(path)
    tmp = path.with_name(f".{path.stem}.tmp{os.getpid()}{path.suffix}")
    rec = _recording()
    try:
        rec.save(str(tmp))
        for i, (result, depth_m, rgb) in enumerate(frames):
            rec.set_time("frame", sequence=i)
            log_result(rec, result, depth_m, rgb)
        rec.flush()
        rec.disconnect()
        os.replace(tmp, path)
    finally:
        if tmp.exists():
            tmp.unlink()
    return path


def write_rrd(
    result: FitResult, path: str | os.PathLike, *, depth_m=None, rgb=None, points=None, point_colors=None
) -> Path:
    """The recording of one frame's result (frame 0) as an ``.rrd`` file (its depth map gives the points;
    ``points``/``point_colors``, a room's, are not used)."""
    return write_rrd_frames([(result, depth_m, rgb)], path)


class RerunStream:
    """Results streamed to a running rerun viewer (``rerun`` started by the user), one frame after the
    other on the ``frame`` timeline. ValueError with one line when no viewer answers at ``url``."""

    def __init__(self, url: str = DEFAULT_VIEWER) -> None:
        import socket
        from urllib.parse import urlparse

        # The SDK connects in the background and only logs when nobody answers: ask the port first.
        where = urlparse(url.replace("rerun+", "", 1))
        try:
            socket.create_connection((where.hostname, where.port or 9876), timeout=2.0).close()
        except OSError as e:
            raise ValueError(
                f"no rerun viewer answers at {where.hostname}:{where.port or 9876} ({e.strerror or e}); "
                "start one with `rerun` first"
            ) from e
        self.rec = _recording()
        self.rec.connect_grpc(url)
        self.frames = 0

    def log(self, result: FitResult, depth_m=None, rgb=None) -> None:
        self.rec.set_time("frame", sequence=self.frames)
        log_result(self.rec, result, depth_m, rgb)
        self.frames += 1

    def add(self, json_path: str | os.PathLike) -> None:
        """Stream a saved result (a frame of a folder, fitted by a worker) with the inputs it records."""
        from cuboidcli.io.result import read_result

        result = read_result(json_path)
        self.log(result, *saved_inputs(result))

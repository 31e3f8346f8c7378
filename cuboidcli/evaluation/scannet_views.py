"""Real room scans seen as posed RGB-D sequences: a scan's coloured points (:mod:`.scannet`'s layout)
rendered into views from a loop of cameras inside the room and written as a TUM folder, so that
``cuboids fit FOLDER`` fits the room the way it fits a recorded sequence, and the scoring can be restricted
to what those views see.

- **Cameras** (:func:`loop_poses`): at :data:`CAMERA_HEIGHT_M` above the floor, on an ellipse around the
  middle of the room's footprint (what the scan holds up to head height, closed and filled) spanning half
  its extent along its principal axes, pulled towards the middle wherever a spot lies nearer than
  :data:`WALL_CLEARANCE_M` to the footprint's edge or :data:`OBSTACLE_CLEARANCE_M` to something standing
  at head height. Every other view looks outward, the rest across the room, all pitched down by
  :data:`PITCH_DEG`; up is the floor's normal, so a scan whose floor is tilted in its frame gets cameras
  levelled to the floor, as a person holds one.
- **Rendering** (:mod:`.splat`): z-buffered discs oriented along the surface, their radius in metres from
  the local point spacing (a 50k-point scan leaves gaps that one-pixel splats would show the walls behind
  through), in pixels from their depth; gaps a farther surface still shows through are emptied and
  single-pixel holes inside one surface filled.
- **Layout** (:func:`write_tum`): ``rgb/``, ``depth/`` (16-bit PNG, :data:`TUM_DEPTH_UNITS` per metre: the
  TUM preset's depth scale, which :func:`cuboidcli.io.sequence.read_sequence` applies to a TUM folder),
  ``rgb.txt``, ``depth.txt``, ``groundtruth.txt`` (``timestamp tx ty tz qx qy qz qw``, camera-to-world,
  OpenCV camera axes). A TUM folder has no camera file: the reader takes the TUM preset scaled to the
  image size, so the views are rendered with exactly that camera (:func:`tum_camera`).
- **What is seen** (:func:`seen_in_view`, :func:`seen_boxes`): a point is seen when some view has it in the
  image, within :data:`SEEN_MAX_DEPTH_M` (the depth the fusion keeps) and no farther than the rendered depth
  there plus a tolerance; a labelled box is seen when at least :data:`BOX_SEEN_SHARE` of its instance's
  points are. :func:`seen_truth` restricts a :class:`.scannet.ScanTruth` to them, for
  :func:`.scannet.scan_metrics`.
"""

from __future__ import annotations

import os
from dataclasses import dataclass, replace
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.evaluation.scannet import ScanTruth
from cuboidcli.evaluation.splat import NEAR_M, render_view, splat_normals, splat_radii, to_camera

#: Views per room by default.
VIEWS = 24
#: Camera height above the floor (m) and the downward pitch of every view (degrees).
CAMERA_HEIGHT_M = 1.45
PITCH_DEG = 20.0
#: A camera stays this far (m) inside the floor's footprint and from anything at head height.
WALL_CLEARANCE_M = 0.6
OBSTACLE_CLEARANCE_M = 0.35
#: Depth PNG units per metre of a TUM folder (the ``tum`` preset's depth scale is 1 / 5000 m).
TUM_DEPTH_UNITS = 5000.0
#: Farthest depth (m) counted as seen: :func:`cuboidcli.load.fuse.fuse_sequence` drops what lies farther.
SEEN_MAX_DEPTH_M = 6.0
#: A point is seen when it lies no farther than the rendered depth plus this much (m, and per metre).
SEEN_TOLERANCE_M = 0.05
SEEN_TOLERANCE_REL = 0.01
#: A labelled box is seen when at least this share of its instance's points is.
BOX_SEEN_SHARE = 0.5
#: Cell size (m) of the grids the density and the footprint are measured on.
_CELL_M = 0.1


def tum_camera(width: int = 320, height: int = 240) -> Camera:
    """The camera a TUM folder of ``width`` x ``height`` depth images is read with: the TUM preset scaled to
    that size, as :func:`cuboidcli.io.sequence.read_sequence` scales it."""
    from cuboidcli.io.depth import intrinsics_for_size, parse_intrinsics

    return intrinsics_for_size(parse_intrinsics(None, "tum"), width, height, preset="tum")


def floor_height(points: np.ndarray, up: np.ndarray, truth: ScanTruth | None = None) -> float:
    """Height along ``up`` of the floor: the median of the points labelled floor, else a low percentile."""
    h = points @ up
    if truth is not None and truth.semantic is not None and np.sum(truth.semantic == 2) >= 100:
        return float(np.median(h[truth.semantic == 2]))
    return float(np.percentile(h, 2))


def _horizontal_axes(up: np.ndarray) -> np.ndarray:
    """(2, 3) two unit vectors orthogonal to ``up`` and each other."""
    seed = np.array([1.0, 0.0, 0.0]) if abs(up[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    a = np.cross(up, seed)
    a /= np.linalg.norm(a)
    return np.stack([a, np.cross(up, a)])


def _fill_enclosed(mask: np.ndarray) -> np.ndarray:
    """``mask`` with its enclosed holes filled (under furniture the floor has no points)."""
    import cv2

    padded = np.pad(mask.astype(np.uint8), 1)
    outside = padded.copy()
    cv2.floodFill(outside, None, (0, 0), 2)
    return (outside != 2)[1:-1, 1:-1] | mask


def look_at(centre: np.ndarray, forward: np.ndarray, up: np.ndarray) -> np.ndarray:
    """(4, 4) camera-to-world pose at ``centre`` looking along ``forward``: OpenCV axes (x right, y down)."""
    z = forward / np.linalg.norm(forward)
    x = np.cross(z, up)
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, :3] = np.stack([x, np.cross(z, x), z], axis=1)
    pose[:3, 3] = centre
    return pose


def loop_poses(
    points: np.ndarray,
    up: np.ndarray,
    floor_h: float,
    views: int = VIEWS,
    height_m: float = CAMERA_HEIGHT_M,
    pitch_deg: float = PITCH_DEG,
) -> list[np.ndarray]:
    """``views`` camera-to-world poses on a loop inside the room (module docstring)."""
    import cv2

    up = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
    axes = _horizontal_axes(up)
    h = points @ up - floor_h
    xy = points @ axes.T
    lo = xy.min(0) - 2 * _CELL_M
    shape = tuple(np.ceil((xy.max(0) + 2 * _CELL_M - lo) / _CELL_M).astype(int) + 1)
    cells = np.floor((xy - lo) / _CELL_M).astype(int)

    def grid(sel):
        g = np.zeros(shape, dtype=bool)
        g[cells[sel, 0], cells[sel, 1]] = True
        return g

    # The footprint: everything the scan holds up to head height, closed over gaps between its walls and
    # filled inside (the floor has no points under furniture, a wall has gaps behind it).
    kernel = np.ones((5, 5), np.uint8)
    floor = grid((h > -0.2) & (h < height_m + 0.4)).astype(np.uint8)
    floor = _fill_enclosed(cv2.morphologyEx(np.pad(floor, 3), cv2.MORPH_CLOSE, kernel)[3:-3, 3:-3] > 0)
    # Anything between knee and above head height is in the way of a person holding the camera.
    obstacle = grid((h > 0.5) & (h < height_m + 0.4))
    to_edge = cv2.distanceTransform(np.pad(floor, 1).astype(np.uint8), cv2.DIST_L2, 5)[1:-1, 1:-1] * _CELL_M
    to_obstacle = cv2.distanceTransform((~obstacle).astype(np.uint8), cv2.DIST_L2, 5) * _CELL_M

    free = floor & (to_edge >= WALL_CLEARANCE_M) & (to_obstacle >= OBSTACLE_CLEARANCE_M)
    for relax in (0.8, 0.6, 0.4):  # a small or crowded room: fewer free spots at lower clearances
        if free.sum() >= 4:
            break
        free = floor & (to_edge >= relax * WALL_CLEARANCE_M) & (to_obstacle >= relax * OBSTACLE_CLEARANCE_M)
    if not free.any():
        free = floor if floor.any() else np.ones(shape, dtype=bool)
    centres = (np.argwhere(free) + 0.5) * _CELL_M + lo
    foot = (np.argwhere(floor) + 0.5) * _CELL_M + lo if floor.any() else centres
    middle = centres.mean(0) if len(centres) else foot.mean(0)
    # The loop's ellipse: half the footprint's extent along its principal axes (5-95 % of its cells).
    evals, evecs = np.linalg.eigh(np.cov((foot - foot.mean(0)).T))
    proj = (foot - foot.mean(0)) @ evecs
    radii = 0.25 * (np.percentile(proj, 95, axis=0) - np.percentile(proj, 5, axis=0))
    cam_h = height_m + floor_h
    pitch = np.radians(pitch_deg)
    poses = []
    for k in range(views):
        theta = 2 * np.pi * k / views
        direction = evecs @ np.array([np.cos(theta), np.sin(theta)])
        target = middle + evecs @ (radii * np.array([np.cos(theta), np.sin(theta)]))
        # Pulled towards the middle until the spot is free; else the free spot nearest to the target.
        spot = None
        for s in np.linspace(1.0, 0.0, 21):
            p = middle + s * (target - middle)
            c = np.floor((p - lo) / _CELL_M).astype(int)
            if (0 <= c).all() and (c < shape).all() and free[c[0], c[1]]:
                spot = p
                break
        if spot is None:
            spot = centres[np.argmin(np.linalg.norm(centres - target, axis=1))]
        look = direction if k % 2 == 0 else -direction
        forward_h = look @ axes
        forward = np.cos(pitch) * forward_h - np.sin(pitch) * up
        poses.append(look_at(spot @ axes + cam_h * up, forward, up))
    return poses


def seen_in_view(points: np.ndarray, depth: np.ndarray, pose: np.ndarray, camera: Camera) -> np.ndarray:
    """(N,) bool: the points that view (``depth`` rendered from ``pose``) sees, the z-buffer test with a
    tolerance (:data:`SEEN_TOLERANCE_M`, :data:`SEEN_TOLERANCE_REL`) within :data:`SEEN_MAX_DEPTH_M`."""
    h, w = depth.shape
    pc = to_camera(points, pose)
    uv, z = camera.project(pc)
    with np.errstate(invalid="ignore"):
        u, v = np.round(uv[:, 0]), np.round(uv[:, 1])
        ok = (z > NEAR_M) & (z <= SEEN_MAX_DEPTH_M) & (u >= 0) & (u < w) & (v >= 0) & (v < h)
    out = np.zeros(len(points), dtype=bool)
    idx = np.flatnonzero(ok)
    d = depth[v[idx].astype(int), u[idx].astype(int)]
    out[idx] = (d > 0) & (z[idx] <= d + SEEN_TOLERANCE_M + SEEN_TOLERANCE_REL * z[idx])
    return out


def box_instances(truth: ScanTruth) -> list[np.ndarray]:
    """For each labelled box the indices of its instance's points: the instance of the box's class with the
    most points inside it (the box files do not name their instance); the points inside it when no labelled
    point of its class is."""
    out = []
    for box, cls in zip(truth.boxes, truth.classes, strict=True):
        inside = np.all(np.abs(truth.points - box.center) <= box.half_size + 0.02, axis=1)
        if truth.instance is not None and truth.semantic is not None:
            ids = truth.instance[inside & (truth.semantic == cls) & (truth.instance > 0)]
            if len(ids):
                out.append(np.flatnonzero(truth.instance == np.bincount(ids).argmax()))
                continue
        out.append(np.flatnonzero(inside))
    return out


def seen_boxes(truth: ScanTruth, seen: np.ndarray, share: float = BOX_SEEN_SHARE) -> np.ndarray:
    """(K,) bool: the labelled boxes of which at least ``share`` of the instance's points is ``seen``."""
    return np.array([len(i) > 0 and seen[i].mean() >= share for i in box_instances(truth)], dtype=bool)


def seen_truth(truth: ScanTruth, seen: np.ndarray, share: float = BOX_SEEN_SHARE) -> ScanTruth:
    """``truth`` restricted to what the views see: the seen points (with their labels) and the boxes seen
    by ``share`` (:func:`seen_boxes`); the up direction stays the whole floor's."""
    keep = seen_boxes(truth, seen, share)

    def part(a):
        return None if a is None else a[seen]

    return replace(
        truth,
        points=truth.points[seen],
        boxes=[b for b, k in zip(truth.boxes, keep, strict=True) if k],
        classes=truth.classes[keep],
        instance=part(truth.instance),
        semantic=part(truth.semantic),
    )


def write_tum(
    folder: str | os.PathLike, depths: list[np.ndarray], rgbs: list[np.ndarray], poses: list[np.ndarray]
) -> Path:
    """Write views (depth metres, rgb uint8, camera-to-world pose) as a TUM folder (module docstring)."""
    import cv2
    import trimesh.transformations as tf

    root = Path(folder)
    (root / "rgb").mkdir(parents=True, exist_ok=True)
    (root / "depth").mkdir(exist_ok=True)
    rgb_lines, depth_lines, pose_lines = ["# color images"], ["# depth maps"], ["# tx ty tz qx qy qz qw"]
    for k, (depth, rgb, pose) in enumerate(zip(depths, rgbs, poses, strict=True)):
        stamp = f"{1.0 + k / 30.0:.6f}"  # 30 Hz, the rgb, depth and pose of a view share one timestamp
        units = np.clip(np.round(depth * TUM_DEPTH_UNITS), 0, 65535).astype(np.uint16)
        cv2.imwrite(str(root / "depth" / f"{stamp}.png"), units)
        cv2.imwrite(str(root / "rgb" / f"{stamp}.png"), cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR))
        qw, qx, qy, qz = tf.quaternion_from_matrix(pose)
        t = pose[:3, 3]
        rgb_lines.append(f"{stamp} rgb/{stamp}.png")
        depth_lines.append(f"{stamp} depth/{stamp}.png")
        pose_lines.append(f"{stamp} {t[0]:.6f} {t[1]:.6f} {t[2]:.6f} {qx:.9f} {qy:.9f} {qz:.9f} {qw:.9f}")
    for name, lines in (("rgb.txt", rgb_lines), ("depth.txt", depth_lines), ("groundtruth.txt", pose_lines)):
        (root / name).write_text("\n".join(lines) + "\n", encoding="utf-8")
    return root


@dataclass
class RenderedScan:
    """A scan written as a TUM folder: its ``poses``, which points the views see (``seen`` (N,) bool) and
    the truth restricted to them (:func:`seen_truth`)."""

    folder: Path
    poses: list[np.ndarray]
    camera: Camera
    seen: np.ndarray
    truth: ScanTruth


def render_points(
    points: np.ndarray,
    colors: np.ndarray,
    poses: list[np.ndarray],
    camera: Camera,
) -> tuple[list[np.ndarray], list[np.ndarray], np.ndarray]:
    """(depths, rgbs, seen (N,) bool) of the points seen from ``poses`` (see :func:`render_view`)."""
    radii, normals = splat_radii(points), splat_normals(points)
    depths, rgbs = [], []
    seen = np.zeros(len(points), dtype=bool)
    for pose in poses:
        depth, rgb = render_view(points, colors, radii, pose, camera, normals)
        depths.append(depth)
        rgbs.append(rgb)
        seen |= seen_in_view(points, depth, pose, camera)
    return depths, rgbs, seen


def render_scan(
    truth: ScanTruth,
    colors: np.ndarray,
    folder: str | os.PathLike,
    views: int = VIEWS,
    width: int = 320,
    height: int = 240,
) -> RenderedScan:
    """Render scan ``truth`` (its points with ``colors`` (N, 3) 0-255) into ``views`` views of
    ``width`` x ``height`` pixels from :func:`loop_poses` and write them as a TUM folder at ``folder``."""
    camera = tum_camera(width, height)
    up = np.asarray(truth.up, dtype=np.float64)
    poses = loop_poses(truth.points, up, floor_height(truth.points, up, truth), views)
    depths, rgbs, seen = render_points(truth.points, np.asarray(colors, dtype=np.uint8), poses, camera)
    root = write_tum(folder, depths, rgbs, poses)
    return RenderedScan(root, poses, camera, seen, seen_truth(truth, seen))


def scan_colors(folder: str | os.PathLike, name: str) -> np.ndarray:
    """(N, 3) uint8 the colours of scan ``name``'s points (``NAME_vert.npy``, else its ``.ply``), in the
    order of :func:`.scannet.read_truth`'s points."""
    vert = Path(folder) / f"{name}_vert.npy"
    if vert.is_file():
        return np.clip(np.load(vert)[:, 3:6], 0, 255).astype(np.uint8)
    from cuboidcli.io.scan import read_scan

    cloud = read_scan(Path(folder) / f"{name}.ply")
    if cloud.colors is None:
        return np.full((len(cloud.points), 3), 128, dtype=np.uint8)
    return np.asarray(cloud.colors, dtype=np.uint8)

"""A whole room scanned from several camera poses, with world-frame ground truth (room-level tests and
benchmarks).

The room is the one :func:`cuboidcli.synth.scene.generate_scene` builds for the same seed (the same layout
stream); the camera then walks a loop inside the room and looks across it, so that together the views see
the walls, the floor and the furniture from several sides. World frame: metres, z up, the floor's top at
z = 0, the room's interior x in [0, size_x], y in [0, size_y] (see :mod:`cuboidcli.synth.room`).

The ground truth holds one box per object seen in any view (:func:`object_boxes`): the room's shell slabs
(kinds ``floor``, ``wall``, ``ceiling``) and every other object (kind ``object``) as the tight upright box,
turned to the object's own yaw, around all its parts and meshes.
"""

from __future__ import annotations

import os
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.io.atomic import atomic_write, atomic_write_json, atomic_write_text
from cuboidcli.io.result import FitResult, read_result, write_result
from cuboidcli.synth.placement import Occupancy
from cuboidcli.synth.render import RayCaster
from cuboidcli.synth.scene import (
    Scene,
    SceneOptions,
    build_world,
    random_streams,
    render_view,
    seed_entropy,
    world_caster,
)
from cuboidcli.synth.view import look_rotation
from cuboidcli.synth.world import World, rot_z

DEPTH_SCALE = 0.001
"""Metres per depth-PNG unit (millimetres)."""
TRUTH_VOXEL_M = 0.02
"""Voxel size of the evaluation points in ``truth_points.npz``, metres."""
SHELL_KINDS = ("floor", "wall", "ceiling")
"""Object categories of the room's shell; they are also the cuboid kinds of their boxes."""
PATH_FRACTION = 0.5
"""The camera loop's semi-axes as a fraction of the free half-extent of the room (inside the margin)."""
WALL_MARGIN_M = 0.7
"""Least distance of a camera position from the room's sides (as :func:`layout.camera_spot`)."""
CAMERA_CLEARANCE_M = 0.3
"""Half-size of the square around a camera position that must not overlap any object (all heights)."""
PITCH_LIMITS_DEG = (-20.0, 0.0)
"""The options' pitch range is clipped to this: a scan looks across the room, slightly down."""


@dataclass
class RoomScan:
    """A room rendered from several poses.

    ``frames`` holds one :class:`Scene` per view (``depth_m`` with sensor noise, ``depth_clean_m``, ``rgb``,
    ``instances``, ``world_from_camera`` (4, 4)); their ``cuboids`` are per-part boxes in each camera's
    frame. ``gt`` is the ground truth in the WORLD frame (z up, metres), one box per object seen in any
    view within the sensor's range, ordered by object id, with extras ``object`` (instance id),
    ``category``, ``visible_px`` (such pixels over all views) and ``views`` (how many views see it).
    ``options`` are the generator's options (the sensor's range bounds what counts as seen).
    """

    camera: Camera
    frames: list[Scene]
    gt: list[Cuboid]
    seed: list[int]
    options: SceneOptions = field(default_factory=SceneOptions)

    @property
    def room(self) -> dict:
        """Room size and openings (``size_m``, ``walls``, ``doorway``), as :attr:`Scene.room`."""
        return self.frames[0].room if self.frames else {}


def _yaw_of(rotation: np.ndarray) -> float:
    """Yaw (radians) of an upright rotation (3, 3): the angle of its x axis in the floor plane."""
    return float(np.arctan2(rotation[1, 0], rotation[0, 0]))


def object_boxes(world: World) -> dict[int, Cuboid]:
    """The tight upright box of every object of ``world`` (world frame), keyed by object id.

    The box is turned to the object's own yaw (that of its first box part, or its meshes' texture frame:
    every part of a placed object shares the placement's rotation) and spans all of the object's part
    corners and mesh vertices. Shell objects (categories floor, wall, ceiling) get that category as their
    kind; everything else (furniture, clutter, door frames) is kind ``object``. Extras: ``object`` (id) and
    ``category``.
    """
    points: dict[int, list[np.ndarray]] = {}
    frames: dict[int, np.ndarray] = {}
    signs = np.array([[x, y, z] for x in (-1, 1) for y in (-1, 1) for z in (-1, 1)], float)
    for p in world.parts:
        points.setdefault(p.object_id, []).append((signs * p.half_size) @ p.rotation.T + p.center)
        frames.setdefault(p.object_id, p.rotation)
    for m in world.meshes:
        points.setdefault(m.object_id, []).append(m.vertices)
        frames.setdefault(m.object_id, m.frame[0])
    boxes = {}
    for oid in sorted(points):
        info = world.object(oid)
        rot = rot_z(_yaw_of(frames[oid]))
        local = np.concatenate(points[oid]) @ rot  # world -> object frame: R^T p, for row vectors p R
        lo, hi = local.min(0), local.max(0)
        kind = info.category if info.category in SHELL_KINDS else "object"
        tags = {"object": oid, "category": info.category}
        boxes[oid] = Cuboid(rot @ ((lo + hi) / 2), (hi - lo) / 2, rot, extras=tags, kind=kind)
    return boxes


def _obstacles(boxes: dict[int, Cuboid]) -> Occupancy:
    """The footprints of every non-shell object, for keeping camera positions clear of furniture."""
    occ = Occupancy()
    for box in boxes.values():
        if box.kind == "object":
            z = [box.center[2] - box.half_size[2], box.center[2] + box.half_size[2]]
            occ.add(box.center[:2], _yaw_of(box.rotation), box.half_size[:2], z)
    return occ


def _position(
    k: int, views: int, phase: float, size: np.ndarray, occ: Occupancy, fallback: np.ndarray
) -> np.ndarray:
    """The floor position (2,) of view ``k``: on an ellipse around the room's centre at angle
    phase + 2 pi k / views, pulled towards the centre (then pushed further out) until clear of furniture;
    ``fallback`` (2,) (the spot build_world kept free) when no candidate is."""
    centre = size[:2] / 2
    free = np.maximum(size[:2] / 2 - WALL_MARGIN_M, 0.0)
    half = [CAMERA_CLEARANCE_M, CAMERA_CLEARANCE_M]
    for f in (PATH_FRACTION, 0.75 * PATH_FRACTION, 1.5 * PATH_FRACTION, 0.5 * PATH_FRACTION, 0.9, 0.25, 0.0):
        for turn in (0.0, 0.25, -0.25):  # radians: a step along the loop before giving up on this radius
            angle = phase + 2.0 * np.pi * k / views + turn
            xy = centre + f * free * np.array([np.cos(angle), np.sin(angle)])
            if not occ.collides(xy, 0.0, half, [-1.0, size[2] + 1.0]):
                return xy
    return np.asarray(fallback, float)


def _view_score(caster: RayCaster, camera: Camera, rotation: np.ndarray, position: np.ndarray) -> float:
    """How usable a view is on a coarse rendering: in-range surface minus a heavy penalty for anything
    closer than 0.5 m (a lens pressed against furniture)."""
    z = caster.cast(camera, rotation, position, step=8).depth_m
    in_range = float(((z >= 0.4) & (z <= 10.0)).mean())
    near = float(((z > 0) & (z < 0.5)).mean())
    return in_range - 100.0 * near


def plan_views(
    world: World,
    caster: RayCaster,
    camera: Camera,
    start: np.ndarray,
    views: int,
    rng: np.random.Generator,
    options: SceneOptions,
) -> list[tuple[np.ndarray, np.ndarray]]:
    """``views`` camera poses (rotation (3, 3) camera-to-world, position (3,) world metres) on a loop.

    View k stands on an ellipse around the room's centre (clear of furniture) and looks back across the
    centre, so the yaws turn once around the room and every wall is seen from the other side of the room;
    pitch is drawn in the options' range clipped to :data:`PITCH_LIMITS_DEG`, roll as in
    :func:`cuboidcli.synth.view.choose_view`, the height stays near ``start``'s (the walker's) height. Of a
    few yaw offsets the one with the best coarse view (:func:`_view_score`) is taken.
    """
    size = np.asarray(world.room["size_m"], float)
    occ = _obstacles(object_boxes(world))
    phase = rng.uniform(-np.pi, np.pi)
    pitch_lo, pitch_hi = np.clip(options.pitch_deg, *PITCH_LIMITS_DEG)
    lo_h, hi_h = options.camera_height_m
    sigma = options.roll_sigma_deg
    poses = []
    for k in range(views):
        xy = _position(k, views, phase, size, occ, start[:2])
        height = float(np.clip(start[2] + rng.uniform(-0.05, 0.05), lo_h, hi_h))
        position = np.array([xy[0], xy[1], height])
        # look through the room's centre; from the centre itself, along the loop's angle turned around
        to_centre = size[:2] / 2 - xy
        angle = phase + 2.0 * np.pi * k / views + np.pi
        yaw = float(np.arctan2(to_centre[1], to_centre[0])) if np.hypot(*to_centre) > 0.2 else angle
        yaw += rng.normal(0.0, np.radians(8.0))
        pitch = np.radians(rng.uniform(pitch_lo, pitch_hi))
        roll = np.radians(np.clip(rng.normal(0.0, sigma), -2.5 * sigma, 2.5 * sigma)) if sigma > 0 else 0.0
        best, best_score = None, -np.inf
        for offset in (0.0, 0.35, -0.35, 0.7, -0.7):
            rot = look_rotation(yaw + offset, pitch, roll)
            score = _view_score(caster, camera, rot, position)
            if score > best_score:
                best, best_score = rot, score
            if score >= 0.9:  # good enough: keep the planned direction
                break
        poses.append((best, position))
    return poses


def generate_room_scan(
    seed: int | Sequence[int],
    views: int = 12,
    camera: Camera | None = None,
    options: SceneOptions | None = None,
) -> RoomScan:
    """Build the room of ``seed`` once and render it from ``views`` poses along a loop (:func:`plan_views`).

    Deterministic for (seed, views, camera, options). The world is the one :func:`generate_scene` builds
    for the same seed. View k's sensor and colour noise come from the streams of the seed (*seed, k), so
    frames do not share noise. ``camera`` defaults to the NYU preset (640x480).
    """
    if views < 1:
        raise ValueError(f"views must be at least 1 (got {views})")
    camera = camera or Camera.preset("nyu")
    options = options or SceneOptions()
    entropy = seed_entropy(seed)
    layout_rng, view_rng, _, _ = random_streams(entropy)
    world, start = build_world(layout_rng, options)
    soup, caster = world_caster(world, options)
    frames = []
    for k, (rotation, position) in enumerate(
        plan_views(world, caster, camera, start, views, view_rng, options)
    ):
        _, _, sensor_rng, rgb_rng = random_streams([*entropy, k])
        frames.append(
            render_view(
                world, soup, caster, camera, rotation, position, options, sensor_rng, rgb_rng, [*entropy, k]
            )
        )
    px = np.zeros(len(world.objects) + 1, np.int64)
    seen_in = np.zeros(len(world.objects) + 1, np.int64)
    for f in frames:
        counts = np.bincount(f.instances[_in_range(f, options)], minlength=px.size)
        px += counts
        seen_in += counts > 0
    gt = []
    for oid, box in object_boxes(world).items():
        if px[oid] > 0:  # the ground truth lists what some view sees within the sensor's range
            box.extras.update(visible_px=int(px[oid]), views=int(seen_in[oid]))
            gt.append(box)
    return RoomScan(camera, frames, gt, entropy, options)


def _in_range(frame: Scene, options: SceneOptions) -> np.ndarray:
    """Pixels (H, W) whose exact depth is within the sensor's range: what the sensor could see."""
    z = frame.depth_clean_m
    return (z >= options.sensor.min_range_m) & (z <= options.sensor.max_range_m) & (frame.instances > 0)


def truth_points(scan: RoomScan, voxel_m: float = TRUTH_VOXEL_M) -> tuple[np.ndarray, np.ndarray]:
    """Evaluation points of a scan: every view's exact depth within the sensor's range, back-projected
    into the world, one point per ``voxel_m`` voxel.

    A voxel keeps its majority instance id (ties: the smaller id) and the mean of that instance's points
    in it, so a point where two objects meet is not pulled between them. Returns points (M, 3) float32
    world metres and instance ids (M,) int32 (the instance image's ids: shell slabs have their own), in
    voxel order.
    """
    pts, ids = [], []
    for f in scan.frames:
        keep = _in_range(f, scan.options)
        cam = scan.camera.backproject(np.where(keep, f.depth_clean_m, 0.0))[keep]
        pose = f.world_from_camera
        pts.append(cam @ pose[:3, :3].T + pose[:3, 3])
        ids.append(f.instances[keep])
    return voxel_majority(np.concatenate(pts), np.concatenate(ids), voxel_m)


def voxel_majority(points: np.ndarray, ids: np.ndarray, voxel_m: float) -> tuple[np.ndarray, np.ndarray]:
    """Down-sample points (N, 3) with labels (N,) to one point per voxel of ``voxel_m`` metres: the
    voxel's majority label (ties: the smaller) and the mean of that label's points in the voxel.
    Returns ((M, 3) float32, (M,) int32), sorted by voxel."""
    points = np.asarray(points, np.float64).reshape(-1, 3)
    ids = np.asarray(ids).ravel().astype(np.int64)
    if points.shape[0] == 0:
        return np.zeros((0, 3), np.float32), np.zeros(0, np.int32)
    cell = np.floor(points / voxel_m).astype(np.int64)
    cell -= cell.min(0)
    dims = cell.max(0) + 1
    key = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
    order = np.lexsort((ids, key))
    key, ids, points = key[order], ids[order], points[order]
    # groups of equal (voxel, label), in voxel then label order
    start = np.flatnonzero(np.r_[True, (key[1:] != key[:-1]) | (ids[1:] != ids[:-1])])
    group = np.repeat(np.arange(start.size), np.diff(np.r_[start, key.size]))
    count = np.bincount(group)
    g_key, g_id = key[start], ids[start]
    # per voxel, the group with the most points; lexsort is stable, so ties keep the smaller label
    best = np.lexsort((-count, g_key))
    first = np.r_[True, g_key[best][1:] != g_key[best][:-1]]
    chosen = best[first]
    sums = np.stack([np.bincount(group, weights=points[:, c], minlength=start.size) for c in range(3)], 1)
    mean = sums[chosen] / count[chosen, None]
    return mean.astype(np.float32), g_id[chosen].astype(np.int32)


def _write_png(path: Path, image: np.ndarray) -> None:
    import cv2

    def write(tmp: Path) -> None:
        if not cv2.imwrite(str(tmp), image):
            raise RuntimeError(f"PNG encoding failed for {path}")

    atomic_write(path, write)


def _matrix_text(matrix: np.ndarray) -> str:
    """A 4x4 matrix as four lines of 12-significant-digit numbers."""
    return "".join(" ".join(f"{v:.12g}" for v in row) + "\n" for row in np.asarray(matrix, float))


def scan_result(scan: RoomScan) -> FitResult:
    """The scan's ground truth as a "cuboids/1" result in the ``world`` frame (z up, metres), with the
    camera the views share, extras ``up``, ``room`` and ``objects`` (every object seen: id, category,
    kind, visible_px and views, summed over the views)."""
    objects = {}
    for f in scan.frames:
        for o in f.objects:
            seen = objects.setdefault(o["id"], {**o, "visible_px": 0, "views": 0})
            seen["visible_px"] += o["visible_px"]
            seen["views"] += 1
    return FitResult(
        camera=scan.camera,
        cuboids=scan.gt,
        settings={
            "generator": "cuboidcli.synth.scan",
            "seed": scan.seed,
            "views": len(scan.frames),
            "options": scan.options.to_dict(),
        },
        frame="world",
        extras={
            "up": [0.0, 0.0, 1.0],
            "room": scan.room,
            "objects": [objects[k] for k in sorted(objects)],
        },
    )


def write_room_scan(root: str | os.PathLike, scan: RoomScan) -> Path:
    """Write a scan in the "plain" sequence layout under ``root`` (each file atomically); returns ``root``.

    ``cameras.json`` {fx, fy, cx, cy, width, height, depth_scale: 0.001}; per view ``NNNNNN``:
    ``depth/NNNNNN.png`` uint16 millimetres of the sensor depth (0 = hole), ``color/NNNNNN.png`` (BGR on
    disk, as OpenCV writes), ``pose/NNNNNN.txt`` the 4x4 camera-to-world matrix (OpenCV camera axes, world
    z up), ``instances/NNNNNN.png`` uint16 instance ids (0 = nothing); ``gt.json`` the world-frame ground
    truth (:func:`scan_result`); ``truth_points.npz`` the evaluation points (:func:`truth_points`:
    ``points`` (M, 3) float32, ``instance`` (M,) int32).
    """
    root = Path(root)
    root.mkdir(parents=True, exist_ok=True)
    cam = scan.camera
    atomic_write_json(
        root / "cameras.json",
        {
            "fx": cam.fx,
            "fy": cam.fy,
            "cx": cam.cx,
            "cy": cam.cy,
            "width": cam.width,
            "height": cam.height,
            "depth_scale": DEPTH_SCALE,
        },
    )
    for k, f in enumerate(scan.frames):
        name = f"{k:06d}"
        depth = np.clip(np.rint(f.depth_m / DEPTH_SCALE), 0, 65535).astype(np.uint16)
        _write_png(root / "depth" / f"{name}.png", depth)
        _write_png(root / "color" / f"{name}.png", np.ascontiguousarray(f.rgb[..., ::-1]))
        _write_png(root / "instances" / f"{name}.png", f.instances.astype(np.uint16))
        atomic_write_text(root / "pose" / f"{name}.txt", _matrix_text(f.world_from_camera))
    write_result(root / "gt.json", scan_result(scan))
    points, instance = truth_points(scan)
    atomic_write(
        root / "truth_points.npz", lambda p: np.savez_compressed(p, points=points, instance=instance)
    )
    return root


def read_scan_truth(root: str | os.PathLike) -> tuple[list[Cuboid], np.ndarray, np.ndarray]:
    """The ground truth of a scan written by :func:`write_room_scan`: (world-frame cuboids, evaluation
    points (M, 3) float32 world metres, instance id per point (M,) int32)."""
    root = Path(root)
    result = read_result(root / "gt.json")
    with np.load(root / "truth_points.npz") as data:
        points, instance = data["points"].astype(np.float32), data["instance"].astype(np.int32)
    return result.cuboids, points, instance

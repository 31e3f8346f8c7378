"""Choosing the camera's orientation: random yaw, pitch and a small roll, kept only if the view is a
reasonable indoor RGB-D frame (mostly valid depth in range, nothing right in front of the lens, some
furniture in sight)."""

from __future__ import annotations

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.synth.mesh import Soup
from cuboidcli.synth.render import RayCaster
from cuboidcli.synth.world import BOXES, World

STRUCTURE = frozenset({"floor", "ceiling", "wall", "door_frame"})


def look_rotation(yaw: float, pitch: float, roll: float) -> np.ndarray:
    """Camera-to-world rotation (3, 3) of an OpenCV camera in a z-up world; angles in radians.

    Columns are the camera's x (right), y (down) and z (forward) axes in world coordinates. ``yaw`` turns
    about the world z axis from +x, ``pitch`` > 0 looks up, ``roll`` turns about the viewing direction.
    """
    forward = np.array([np.cos(pitch) * np.cos(yaw), np.cos(pitch) * np.sin(yaw), np.sin(pitch)])
    right = np.cross(forward, [0.0, 0.0, 1.0])
    right /= np.linalg.norm(right)
    down = np.cross(forward, right)  # right x down = forward, as in the OpenCV frame
    c, s = np.cos(roll), np.sin(roll)
    return np.stack([c * right + s * down, -s * right + c * down, forward], axis=1)


def choose_view(
    caster: RayCaster,
    camera: Camera,
    position: np.ndarray,
    soup: Soup,
    world: World,
    rng: np.random.Generator,
    pitch_deg: tuple[float, float] = (-30.0, 10.0),
    roll_sigma_deg: float = 2.0,
    attempts: int = 40,
) -> np.ndarray:
    """A camera-to-world rotation (3, 3) for a camera at ``position`` (3,), world metres.

    Views are drawn at random and checked on a coarse (every 8th pixel) rendering: at least 70 % of the
    pixels see a surface 0.4-10 m away, under 1 % closer than 0.5 m, median depth 1-7 m, and at least
    three non-structural objects are visible, two of them made of boxes. The first view that passes is
    taken; if none does, the best seen.
    """
    furniture = np.array([o.category not in STRUCTURE for o in world.objects])
    boxy = furniture & np.array([o.kind == BOXES for o in world.objects])
    best, best_score = None, -np.inf
    for _ in range(attempts):
        yaw = rng.uniform(-np.pi, np.pi)
        pitch = np.radians(rng.uniform(*pitch_deg))
        roll = np.radians(
            np.clip(rng.normal(0.0, roll_sigma_deg), -2.5 * roll_sigma_deg, 2.5 * roll_sigma_deg)
        )
        rot = look_rotation(yaw, pitch, roll)
        hits = caster.cast(camera, rot, position, step=8)
        z = hits.depth_m
        in_range = (z >= 0.4) & (z <= 10.0)
        near = float((hits.hit & (z < 0.5)).mean())
        valid = float(in_range.mean())
        median = float(np.median(z[in_range])) if in_range.any() else 0.0
        ids = soup.object_id[hits.face[hits.hit]]
        counts = np.bincount(ids, minlength=len(world.objects) + 1)[1:]
        n_objects = int(((counts >= 3) & furniture).sum())
        n_boxy = int(((counts >= 3) & boxy).sum())
        good = valid >= 0.7 and near <= 0.01 and 1.0 <= median <= 7.0
        if good and n_objects >= 3 and n_boxy >= 2:
            return rot
        score = n_objects + n_boxy + valid + (10.0 if good else 0.0) - 100.0 * near
        if score > best_score:
            best, best_score = rot, score
    return best

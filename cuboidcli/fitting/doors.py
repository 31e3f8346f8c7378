"""Doors that the fit gave a wall cuboid of their own.

A room's fit takes what lies flat in a wall's plane for the wall. Where a sequence's views see a door apart
from its wall (open, or in another paint), the door gets a wall cuboid of its own: an upright slab of a
door's size (:data:`~cuboidcli.fitting.not_objects.DOOR_PANEL_WIDTH_M` wide, at least
:data:`~cuboidcli.fitting.not_objects.DOOR_PANEL_HEIGHT_M` tall, standing on the floor) in the plane of a
larger wall beside it. Such a slab is a door when its colour differs from that wall's by at least
:data:`DOOR_COLOUR`: a door-sized stretch in the wall's own colour is the wall (between two doors, beside a
cupboard). The slab stays in the room's shell, and the door gets an object box as well: upright, along the
wall, from the floor to the slab's top, :data:`DOOR_DEPTH_M` deep at least (a door fills its opening
through the wall, frame and leaf).

On the sequences rendered from the 10 real ScanNet scans (the saved fits of seeds 0-4, grouped again) 11
slabs passed, 8 of them on one labelled object, all doors, and 8 labelled doors more were matched at IoU
0.25: recall 56.1 -> 57.5 % (the five seeds' mean), precision 74.7 % before and after. The 8 are the doors
of one room, in its three scans, so the evidence is thin. On the scans, where a door lies in its wall's
cuboid, one slab passed in five seeds (docs/scenes.md). Numpy, float64.
"""

from __future__ import annotations

import math

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.not_objects import door_panel

#: A door's median colour differs from its wall's by at least this much (Euclidean, RGB 0-255). On the
#: sequences (seeds 0-4) 20 / 30 / 40 gave recall 57.7 / 57.5 / 56.8 % at precision 74.6 / 74.7 / 74.7 %.
DOOR_COLOUR = 30.0
#: The door's box is at least this deep across its wall (m).
DOOR_DEPTH_M = 0.1
#: The larger wall beside a door: parallel within :data:`DOOR_WALL_TILT_DEG`, its plane within
#: :data:`DOOR_WALL_GAP_M` (m) of the door's centre, and the door's centre at most a door's width beyond
#: its end.
DOOR_WALL_TILT_DEG = 10.0
DOOR_WALL_GAP_M = 0.3
#: A slab needs this many inliers to be looked at.
DOOR_MIN_POINTS = 20


def _turn(theta: float) -> np.ndarray:
    c, s = math.cos(theta), math.sin(theta)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


def _upright_axes(c: Cuboid, R: np.ndarray) -> tuple[int, int] | None:
    """The local axes of ``c`` that are its normal (the thinnest) and its horizontal one, when ``c`` is an
    upright slab (its normal within 11.5 degrees of level in the level frame of ``R``), else None."""
    axes = R.T @ c.rotation
    k = int(np.argmin(c.half_size))
    if abs(axes[2, k]) > 0.2:
        return None
    rest = [a for a in range(3) if a != k]
    return k, min(rest, key=lambda a: abs(axes[2, a]))


def _gap(c: Cuboid, w: Cuboid, R: np.ndarray) -> float | None:
    """How far the slab ``c``'s centre lies from the plane of the larger wall ``w`` (m) when ``w`` is beside
    it (parallel, within :data:`DOOR_WALL_GAP_M` of its plane, along it), else None."""
    own, other = _upright_axes(c, R), _upright_axes(w, R)
    if own is None or other is None:
        return None
    n, m = c.rotation[:, own[0]], w.rotation[:, other[0]]
    if abs(float(n @ m)) < math.cos(math.radians(DOOR_WALL_TILT_DEG)):
        return None
    d = c.center - w.center
    gap = abs(float(d @ m))
    along = abs(float(d @ w.rotation[:, other[1]])) - w.half_size[other[1]]
    return gap if gap <= DOOR_WALL_GAP_M and along <= 2.0 * c.half_size[own[1]] else None


def door_walls(
    level: np.ndarray,
    labels: np.ndarray,
    cuboids: list[Cuboid],
    R: np.ndarray,
    under: np.ndarray,
    colors: np.ndarray | None,
) -> list[tuple[int, Cuboid, np.ndarray, np.ndarray, np.ndarray]]:
    """The doors among a room's wall cuboids (module docstring).

    ``level`` (M, 3) are the fitting points in the room's level frame (``R`` turns it to the world, its z
    the room's up), ``labels`` (M,) their cuboid, ``under`` (M,) the floor's height under each point and
    ``colors`` (M, 3) their colours (None: no door is told from its wall). Each door as (the wall cuboid's
    index, its upright box in the world frame, its inliers in the box's level frame, and the box's lower and
    upper corners there), for :func:`~cuboidcli.fitting.objects.object_score`."""
    if colors is None:
        return []
    colors = np.asarray(colors, dtype=np.float64).reshape(-1, 3)
    walls = [i for i, c in enumerate(cuboids) if c.kind == "wall"]
    area = {i: float(np.prod(np.sort(cuboids[i].half_size)[1:])) for i in walls}
    out = []
    for i in walls:
        c = cuboids[i]
        axes = _upright_axes(c, R)
        members = np.flatnonzero(labels == i)
        if axes is None or len(members) < DOOR_MIN_POINTS:
            continue
        along = (R.T @ c.rotation)[:, axes[1]]
        turn = _turn(math.atan2(along[1], along[0]))
        corners = (c.corners() @ R) @ turn
        lo, hi = corners.min(0), corners.max(0)
        floor_z = float(np.median(under[members]))
        if not door_panel(float(hi[0] - lo[0]), float(hi[2] - floor_z), float(lo[2] - floor_z)):
            continue
        gaps = {j: _gap(c, cuboids[j], R) for j in walls if area[j] > area[i]}
        beside = {j: g for j, g in gaps.items() if g is not None}
        if not beside:
            continue
        j = min(beside, key=beside.get)
        own, theirs = np.median(colors[members], axis=0), np.median(colors[labels == j], axis=0)
        if np.linalg.norm(own - theirs) < DOOR_COLOUR:
            continue
        lo[2] = floor_z
        middle, half = (lo[1] + hi[1]) / 2, max((hi[1] - lo[1]) / 2, DOOR_DEPTH_M / 2)
        lo[1], hi[1] = middle - half, middle + half
        rotation = R @ turn
        box = Cuboid(rotation @ ((lo + hi) / 2), (hi - lo) / 2, rotation, kind="object")
        out.append((i, box, level[members] @ turn, lo, hi))
    return out

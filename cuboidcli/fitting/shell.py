"""The room's shell told from what stands in the room, without labels: a slab with (almost) nothing beyond
it, seen from inside, is a wall, the floor or the ceiling (:func:`is_room_slab`), and what each box is
(:func:`cuboid_kind`: floor, wall, ceiling or object). Numpy, float64; boxes as (3,) centre, (3,)
half-sizes and (3, 3) rotation arrays."""

from __future__ import annotations

import math

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.box import thin_axis

#: A slab is part of the room's shell when at most ``ROOM_SHARE`` of the frame's points lie more than
#: ``ROOM_MARGIN_M`` beyond it (seen from the camera): nothing is behind a wall, under the floor or above
#: the ceiling, while a table top has the floor under it and a cabinet front the wall behind it.
ROOM_SHARE = 0.05
ROOM_MARGIN_M = 0.15
#: Seen from inside a room, an upright slab with more than this share of all the room's points beyond it
#: stands in the room (a monitor, a cabinet's side), whatever little is seen right behind it.
ROOM_WIDE_SHARE = 0.25
#: A slab is upright (a wall, a cabinet's side) when the cosine of its normal with up is below this: more
#: than 60 degrees from vertical.
UPRIGHT_NORMAL_COS = 0.5
#: A room slab is a floor or ceiling when its thickness axis is within this angle of gravity, a wall when
#: within it of horizontal; between the two it stays an object (a ramp, a tilted panel).
KIND_ANGLE_DEG = 20.0


def beyond_share(
    points: np.ndarray,
    center: np.ndarray,
    half: np.ndarray,
    rotation: np.ndarray,
    k: int,
    viewpoint: np.ndarray | None = None,
    up: np.ndarray | None = None,
) -> float:
    """The share of ``points`` (N, 3) that lie more than :data:`ROOM_MARGIN_M` beyond the far face of a
    slab with thickness axis ``k`` (the face away from ``viewpoint``, None = the camera at the origin),
    along its normal. Seen from a ``viewpoint`` inside a room, only the points behind an upright slab
    itself (within its rectangle, grown by the margin; ``up`` (3,) says which slabs are upright) count: a
    whole room holds more beyond any one wall's plane than a frame's field of view does (a corridor seen
    through another wall's door), while a floor still has nothing anywhere below it; an upright slab with
    more than :data:`ROOM_WIDE_SHARE` of all the points beyond it gets that share (it stands in the room:
    the space right behind it is hidden by it, not empty)."""
    if points.shape[0] == 0:
        return 0.0
    n = rotation[:, k]
    if n @ (center if viewpoint is None else center - viewpoint) < 0:
        n = -n
    far = float(n @ center) + float(half[k])
    beyond = points @ n > far + ROOM_MARGIN_M
    if viewpoint is not None and up is not None and abs(float(n @ up)) < UPRIGHT_NORMAL_COS:
        wide = float(np.mean(beyond))
        if wide > ROOM_WIDE_SHARE:  # a quarter of the room behind it: something standing in the room
            return wide
        local = (points - center) @ rotation
        for j in range(3):
            if j != k:
                beyond &= np.abs(local[:, j]) <= half[j] + ROOM_MARGIN_M
    return float(np.mean(beyond))


def is_room_slab(
    points: np.ndarray,
    center: np.ndarray,
    half: np.ndarray,
    rotation: np.ndarray,
    viewpoint: np.ndarray | None = None,
    up: np.ndarray | None = None,
) -> bool:
    """Whether a box is a slab of the room's shell (wall, floor, ceiling): a slab (:func:`thin_axis`) with
    at most :data:`ROOM_SHARE` of the frame's ``points`` (N, 3) beyond it seen from ``viewpoint``
    (:func:`beyond_share`). This needs no labels; a slab on furniture standing against a wall (a bookcase's
    side) can pass it too."""
    k = thin_axis(np.asarray(half, dtype=np.float64))
    return k >= 0 and beyond_share(points, center, half, rotation, k, viewpoint, up) <= ROOM_SHARE


def cuboid_kind(
    points: np.ndarray, cuboid: Cuboid, down: np.ndarray, viewpoint: np.ndarray | None = None
) -> str:
    """floor, wall, ceiling or object: a slab of the room's shell (:func:`is_room_slab` against the frame's
    ``points`` (N, 3), seen from ``viewpoint``, None = the camera at the origin) by the direction of its
    thickness against ``down`` (3,), unit: level and below the viewpoint a floor, level and above it a
    ceiling, upright a wall."""
    c, a, R = cuboid.center, cuboid.half_size, cuboid.rotation
    if not is_room_slab(points, c, a, R, viewpoint, -down):
        return "object"
    cos = abs(float(R[:, thin_axis(a)] @ down))
    if cos >= math.cos(math.radians(KIND_ANGLE_DEG)):
        below = float((c if viewpoint is None else c - viewpoint) @ down) > 0
        return "floor" if below else "ceiling"
    if cos <= math.sin(math.radians(KIND_ANGLE_DEG)):
        return "wall"
    return "object"

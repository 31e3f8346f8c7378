"""Alignment of a (refined, grown) winner to gravity or to the room's Manhattan frame, with its extents
re-fitted to its inliers: tight, upright boxes (ours; the paper selects free boxes). The room's shell (a
wall, the floor, the ceiling: :func:`~cuboidcli.fitting.shell.is_room_slab`) keeps the room's axes at a
larger loss of gain than other boxes do.
"""

from __future__ import annotations

from dataclasses import dataclass, replace

import numpy as np

from cuboidcli.fitting.box import Box, Scored, StepContext, thin_axis
from cuboidcli.fitting.refit import plane_sweep, refit_box
from cuboidcli.fitting.shell import is_room_slab
from cuboidcli.fitting.winner import grow_cuboid, shrink_cuboid
from cuboidcli.geometry.arrays import count, indices, numpy64
from cuboidcli.geometry.gravity import level_frame, manhattan_rotation, upright_rotation
from cuboidcli.geometry.inlier import INLIER_CUT

#: An aligned winner replaces the free one only while it keeps this share of the free one's gain: a box
#: that is really tilted (a leaning board, a wrong gravity) stays free rather than fit badly.
ALIGN_KEEP = 0.8
#: A slab of the room's shell (a wall, the floor, the ceiling: :func:`is_room_slab`) takes the room's axes, or
#: stands upright, while it keeps this share of its free gain. Kinect depth bends far walls by several
#: degrees, so a wall measured 5 m away fits its own tilted plane better than the true, vertical one.
ROOM_KEEP = 0.5
#: Manhattan axes are preferred over a free yaw unless the free yaw gains this share more.
MANHATTAN_SLACK = 0.02
#: :func:`edge_to_vertical` turns a slab to a direction only when that direction's projection onto the
#: slab's plane is at least this long (unit vectors): a level slab has no upright edge to turn to.
MIN_IN_PLANE = 0.3


@dataclass(frozen=True)
class Alignment:
    """The constraint on the orientation of selected cuboids."""

    mode: str
    """"gravity" (one axis vertical, free yaw) or "manhattan" (the room's axes, or a free yaw where that
    fits better)."""
    up: np.ndarray
    """(3,) unit up vector in camera coordinates."""
    axes: np.ndarray | None = None
    """(3, 3) the room's axes (columns: up, two horizontal), for "manhattan"; None = gravity only."""
    viewpoint: np.ndarray | None = None
    """(3,) where the room is seen from when telling its shell from furniture (:func:`is_room_slab`): the
    camera (None: the origin of a frame's coordinates) or a point inside a scanned room."""

    def frame(self) -> np.ndarray:
        """(3, 3) world axes as columns in camera coordinates, the third one up: the room's horizontal axes
        when known, else two horizontal directions (the first from the camera's x axis)."""
        if self.axes is None:
            return level_frame(self.up)
        up = self.up / np.linalg.norm(self.up)
        h1 = self.axes[:, 1] - (self.axes[:, 1] @ up) * up
        h1 = h1 / np.linalg.norm(h1)
        return np.stack([h1, np.cross(up, h1), up], 1)


def align_winner(scored: Scored, ctx: StepContext, alignment: Alignment) -> Scored:
    """Turn a (refined, grown) winner upright or onto the room's axes, re-fit its extents to the points it
    explains, and grow it again.

    Candidates: the nearest upright rotation (same yaw, :func:`upright_rotation`) and, for "manhattan",
    the nearest signed permutation of the room's axes (:func:`manhattan_rotation`; always taken by slabs,
    the walls, floor and ceiling of a room, and by other boxes unless the free yaw gains
    ``MANHATTAN_SLACK`` more). Each candidate keeps the winner's centre and sizes, its faces are
    moved onto the winner's new inliers (:func:`~cuboidcli.fitting.refit.refit_box`), and it grows like
    any winner. The best candidate replaces the winner when it keeps ``ALIGN_KEEP`` of its gain (a
    Manhattan one that does not falls back to the upright one); a slab of the room's shell
    (:func:`is_room_slab`) needs to keep only ``ROOM_KEEP``, and when its candidate falls short of that,
    the candidate is also tried on the plane most of its points lie on
    (:func:`~cuboidcli.fitting.refit.plane_sweep`) with its edges trimmed off anything seen beyond it
    (:func:`~cuboidcli.fitting.winner.shrink_cuboid`), grown again, and the better one kept. A slab for
    which neither holds keeps its plane and is turned in it to upright edges (:func:`edge_to_vertical`)
    when that keeps ``ALIGN_KEEP`` of its gain.
    Returns the winner with its ``kind``: "manhattan", "gravity", "tilted" (a slab in its own plane, edges
    turned upright) or "free" (kept as it was).
    """
    config, gain = ctx.config, scored.gain
    inl = ctx.newly_explained(scored.values)
    if count(inl) < config.min_set:
        inl = indices(scored.values >= INLIER_CUT)
    if count(inl) < config.min_set:
        return replace(scored, kind="free")
    p = numpy64(ctx.points[inl])
    c0, a0, r0 = scored.box.numpy()

    all_pts = numpy64(ctx.points)
    room = is_room_slab(all_pts, c0, a0, r0, alignment.viewpoint, alignment.up)
    # the room's shell stands on the room's axes even where bent depth fits a tilted plane a little better
    keep = ROOM_KEEP if room else ALIGN_KEEP

    def place(on: np.ndarray, rot: np.ndarray, kind: str) -> Scored:
        cn, an = refit_box(on, c0, a0, rot, config.a_min)
        return ctx.score(Box.from_numpy(cn, an, rot, like=scored.box.center), kind)

    def grown(placed: Scored) -> Scored:
        if placed.gain <= 0.0:  # nothing to grow from
            return placed
        return grow_cuboid(placed, ctx)

    def candidate(kind: str, rot: np.ndarray) -> Scored:
        placed = place(p, rot, kind)
        best = grown(placed)  # grow_cuboid works on copies: ``placed`` stays as it is
        if room and best.gain < keep * gain:
            # a wall in bent far depth: the plane most of its points lie on; a doorway or a mirror that
            # the turned wall now covers: its edges trimmed
            on = plane_sweep(all_pts, numpy64(ctx.state), p, rot, _thin_of(rot, r0, a0))
            if on.shape[0] >= config.min_set:
                alt = place(on, rot, kind)
                if alt.gain > placed.gain:
                    placed = alt
            other = grown(shrink_cuboid(placed, ctx))
            if other.gain > best.gain:
                best = other
        return best

    if alignment.mode == "manhattan" and alignment.axes is not None:
        best = candidate("manhattan", manhattan_rotation(r0, alignment.axes, thin_axis(a0)))
        slab = best.box.thin_axis() >= 0
        if not (slab and best.gain >= keep * gain):  # a slab on the room's axes needs no other
            upright = candidate("gravity", upright_rotation(r0, alignment.up))
            free_yaw_wins = upright.gain > best.gain + MANHATTAN_SLACK * abs(best.gain)
            if (not slab and free_yaw_wins) or best.gain < keep * gain:
                best = upright  # off the room's axes, maybe still upright
    else:
        best = candidate("gravity", upright_rotation(r0, alignment.up))
    if best.gain >= keep * gain:
        return best
    rot = edge_to_vertical(r0, thin_axis(a0), alignment)
    if rot is not None:
        tilted = candidate("tilted", rot)
        if tilted.gain >= ALIGN_KEEP * gain:
            return tilted
    return replace(scored, kind="free")


def _thin_of(rot: np.ndarray, r0: np.ndarray, a0: np.ndarray) -> int:
    """The axis of ``rot`` nearest to the thickness axis of the slab with axes r0 and half-sizes a0."""
    n = r0[:, thin_axis(a0)]
    return int(np.argmax(np.abs(rot.T @ n)))


def edge_to_vertical(rot: np.ndarray, k: int, alignment: Alignment) -> np.ndarray | None:
    """A slab's axes (3, 3) turned in its own plane (thickness axis k kept) so that one edge is as vertical
    as the plane allows; for a level slab (floor, table top) one edge along the room's first horizontal
    axis. A wall measured with a tilt (far Kinect depth bends) then stands with upright edges instead of
    as a rhombus. None when k < 0 (not a slab) or when there is no direction to turn to."""
    if k < 0:
        return None
    n = rot[:, k]
    target = alignment.up - (alignment.up @ n) * n
    if np.linalg.norm(target) < MIN_IN_PLANE and alignment.axes is not None:  # level: take a room axis
        h = alignment.axes[:, 1]
        target = h - (h @ n) * n
    norm = np.linalg.norm(target)
    if norm < MIN_IN_PLANE:
        return None
    target = target / norm
    i, j = [m for m in range(3) if m != k]
    if abs(rot[:, j] @ target) > abs(rot[:, i] @ target):
        i, j = j, i
    out = rot.copy()
    out[:, i] = target if rot[:, i] @ target >= 0 else -target
    out[:, j] = np.cross(out[:, k], out[:, i])
    if np.linalg.det(out) < 0:
        out[:, j] = -out[:, j]
    return out

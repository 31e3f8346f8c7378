"""What happens to the winner of a step before it joins the set (paper Sec. 3.2 selects it as drawn; the
refinements here are ours): refinement on the points it newly explains, growing face by face to where its
surface ends, and, when asked, alignment to gravity or to the room's Manhattan frame with extents re-fitted
to its inliers (tight, upright boxes).

All functions take one cuboid as (1, 3) centre, (1, 3) half-sizes and (1, 3, 3) rotation tensors (columns
= the cuboid's axes, OpenCV camera frame, metres) and the points' current state (N,). Values and refinement
are computed by the fit's backend (:mod:`cuboidcli.fitting.backend`), passed as ``backend``; where it is
left out (None), the default backend of the points' device.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import torch

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.backend import ScoreParams, ScoringBackend, backend_for
from cuboidcli.fitting.config import FitConfig
from cuboidcli.geometry.gravity import level_frame, manhattan_rotation, upright_rotation
from cuboidcli.geometry.kernels import combine

#: An aligned winner replaces the free one only while it keeps this share of the free one's gain: a box
#: that is really tilted (a leaning board, a wrong gravity) stays free rather than fit badly.
ALIGN_KEEP = 0.8
#: A slab of the room's shell (a wall, the floor, the ceiling: :func:`is_room_slab`) takes the room's axes, or
#: stands upright, while it keeps this share of its free gain. Kinect depth bends far walls by several
#: degrees, so a wall measured 5 m away fits its own tilted plane better than the true, vertical one.
ROOM_KEEP = 0.5
#: A slab is part of the room's shell when at most ``ROOM_SHARE`` of the frame's points lie more than
#: ``ROOM_MARGIN_M`` beyond it (seen from the camera): nothing is behind a wall, under the floor or above
#: the ceiling, while a table top has the floor under it and a cabinet front the wall behind it.
ROOM_SHARE = 0.05
ROOM_MARGIN_M = 0.15
#: Seen from inside a room, an upright slab with more than this share of all the room's points beyond it
#: stands in the room (a monitor, a cabinet's side), whatever little is seen right behind it.
ROOM_WIDE_SHARE = 0.25
#: Manhattan axes are preferred over a free yaw unless the free yaw gains this share more.
MANHATTAN_SLACK = 0.02
#: A slab turned to the tightest rectangle around its points (:func:`square_slab`) is kept when it gains
#: this share of what the solver's in-plane angle gains, both grown.
SQUARE_KEEP = 0.995
#: Face moves tried first when a slab thickens (m); the pull-back after growing trims an overshoot.
THICKEN_STEPS_M = (0.6, 0.3)
#: In-plane angles tried for the tightest rectangle (radians).
SQUARE_ANGLES = np.deg2rad(np.arange(0.0, 90.0, 2.0))
#: A slab whose tightest rectangle is within this angle (radians) of its own is left as it is.
SQUARE_MIN_TURN = np.deg2rad(3.0)
#: A point lies on a face plane of an aligned box when it is this close to it (m); about tau.
FACE_BAND_M = 0.06


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


def refine_winner(
    pts,
    c,
    a,
    R,
    values,
    state,
    gain,
    sp: ScoreParams,
    config: FitConfig,
    gen: torch.Generator,
    backend: ScoringBackend | None = None,
):
    """Refine the winner on the points it newly explains, grow it face by face
    (:func:`grow_cuboid`), and refine the grown box again. Each result is kept only if the gain holds."""
    backend = backend or backend_for("auto", pts.device)
    c, a, R, values, gain = _refine_once(pts, c, a, R, values, state, gain, sp, config, gen, backend)
    if config.grow_rounds < 1:
        return c, a, R, values, gain
    best = _grow_and_refine(pts, c, a, R, values, state, gain, sp, config, gen, backend)
    square = square_slab(pts, c, a, R, values, state, config)
    if square is not None:
        c2, a2, R2 = square
        v2 = values_one(pts, c2, a2, R2, sp, backend)
        other = _grow_and_refine(pts, c2, a2, R2, v2, state, gain_of(v2, state), sp, config, gen, backend)
        if other[4] >= SQUARE_KEEP * best[4]:
            best = other
    return best


def _grow_and_refine(pts, c, a, R, values, state, gain, sp: ScoreParams, config: FitConfig, gen, backend):
    c2, a2, values2, gain2 = grow_cuboid(pts, c, a, R, state, gain, sp, config, backend)
    if gain2 <= gain:
        return c, a, R, values, gain
    return _refine_once(pts, c2, a2, R, values2, state, gain2, sp, config, gen, backend)


def square_slab(pts, c, a, R, values, state, config: FitConfig):
    """A slab turned in its plane to the tightest rectangle around the points it newly explains, its
    extents re-fitted to them (:func:`_refit_box`): a six-point box on a table top or a cabinet front is at
    a random in-plane angle, which the inlier count cannot see but growing its edges and its thickness
    can. Returns (center, half, rotation) as (1, ...) tensors, or None for a box that is not a slab or is
    already turned that way."""
    k = thin_axis(a[0].cpu().numpy())
    if k < 0:
        return None
    inl = ((values >= 0.5) & (values > state)).nonzero().squeeze(1)
    if inl.numel() < config.min_set:
        return None
    p = pts[inl].double().cpu().numpy()
    r0 = R[0].double().cpu().numpy()
    i, j = [m for m in range(3) if m != k]
    uv = (p - p.mean(0)) @ r0[:, [i, j]]
    cs, sn = np.cos(SQUARE_ANGLES), np.sin(SQUARE_ANGLES)
    x = uv @ np.stack([cs, sn])  # (M, angles): coordinates along the rotated first axis
    y = uv @ np.stack([-sn, cs])
    lo_hi = np.percentile(np.concatenate([x, y], 1), [1.0, 99.0], axis=0)
    extent = lo_hi[1] - lo_hi[0]
    n = len(SQUARE_ANGLES)
    best = SQUARE_ANGLES[int(np.argmin(extent[:n] * extent[n:]))]
    if min(best, np.pi / 2 - best) < SQUARE_MIN_TURN:  # already the tightest rectangle
        return None
    cs, sn = np.cos(best), np.sin(best)
    rot = r0.copy()
    rot[:, i], rot[:, j] = cs * r0[:, i] + sn * r0[:, j], -sn * r0[:, i] + cs * r0[:, j]
    half = a[0].double().cpu().numpy()
    cn, an = _refit_box(p, c[0].double().cpu().numpy(), half, rot, config.a_min)
    return tuple(torch.from_numpy(x)[None].to(device=c.device, dtype=c.dtype) for x in (cn, an, rot))


def grow_cuboid(pts, c, a, R, state, gain, sp: ScoreParams, config: FitConfig, backend=None):
    """Push each face of a cuboid outwards while the inlier-count gain rises (region growing).

    A minimal set of six points spans only part of a wall, a floor or a table top, and the solver's box
    ends at those points. Each round tries every face (for a slab, the faces across its thickness, an
    axis under a quarter of the middle one, stay): first a step of half the box's extent along that axis
    (at least ``config.grow_step_m``), then a step of ``grow_step_m``; a move is kept when the gain rises,
    and a face that cannot move is done. Sizes stay within a_max (a slab's two long axes within
    ``config.slab_max_m``: a wall or a floor may be longer than 2 a_max). A big step may overshoot into space
    without points, so each face is then pulled back in steps of 0.8 ... ``grow_step_m`` m as long as the
    gain drops by less than 0.1 %: the box ends where its surface ends. Returns (center, half, values,
    gain) with (1, 3) tensors; the inputs when nothing grew."""
    c = c.clone()
    a = a.clone()
    grown = False
    axes = R[0].double()
    slab_axis = thin_axis(a[0].cpu().numpy())
    faces = [(k, sgn) for k in range(3) if k != slab_axis or config.grow_thickness for sgn in (1.0, -1.0)]
    slab_cap = config.a_max if config.slab_max_m is None else max(config.a_max, config.slab_max_m)
    caps = [config.a_max if slab_axis < 0 or k == slab_axis else slab_cap for k in range(3)]
    done: set = set()
    for _ in range(config.grow_rounds):
        moved = False
        for k, sgn in faces:
            if (k, sgn) in done:
                continue
            grew = False
            if k == slab_axis:  # a slab's thickness: its new faces hold points only past an edge
                steps = THICKEN_STEPS_M + (config.grow_step_m,)
            else:
                steps = (max(float(a[0, k]), config.grow_step_m), config.grow_step_m)
            for step in steps:
                new_half = min(float(a[0, k]) + 0.5 * step, caps[k])
                grow = new_half - float(a[0, k])
                if grow <= 1e-6:
                    break
                c2, a2, g2 = _move_face(pts, c, a, R, axes, k, sgn, grow, state, sp, backend)
                if g2 > gain + 1e-6:
                    c, a, gain, grew, grown = c2, a2, g2, True, True
                    break
            if grew:
                moved = True
            else:
                done.add((k, sgn))
        if not moved:
            break
    if grown:
        # big steps may overshoot into space without points: pull each face back while no gain is lost
        floor = gain - 1e-3 * abs(gain)
        for k, sgn in faces:
            for step in (0.8, 0.4, 0.2, config.grow_step_m):
                while float(a[0, k]) - 0.5 * step >= config.a_min:
                    c2, a2, g2 = _move_face(pts, c, a, R, axes, k, sgn, -0.5 * step, state, sp, backend)
                    if g2 < floor:
                        break
                    c, a, gain = c2, a2, g2
    return c, a, values_one(pts, c, a, R, sp, backend), gain


def shrink_cuboid(pts, c, a, R, state, gain, sp: ScoreParams, config: FitConfig, backend=None):
    """Pull faces of a cuboid inwards while the inlier-count gain rises: a slab turned onto the room's axes
    may cover points seen beyond it (through a doorway, in a mirror), which count against it, until its
    edges move in. A slab's thickness stays. Returns (center, half, values, gain)."""
    axes = R[0].double()
    slab_axis = thin_axis(a[0].cpu().numpy())
    faces = [(k, sgn) for k in range(3) if k != slab_axis for sgn in (1.0, -1.0)]
    for _ in range(config.grow_rounds):
        moved = False
        for k, sgn in faces:  # the best of the steps, so that a big one does not cut into the surface
            moves = [
                _move_face(pts, c, a, R, axes, k, sgn, -0.5 * step, state, sp, backend)
                for step in (0.8, 0.4, 0.2, config.grow_step_m)
                if float(a[0, k]) - 0.5 * step >= config.a_min
            ]
            best = max(moves, key=lambda m: m[2], default=None)
            if best is not None and best[2] > gain + 1e-6:
                c, a, gain = best
                moved = True
        if not moved:
            break
    return c, a, values_one(pts, c, a, R, sp, backend), gain


def _move_face(pts, c, a, R, axes, k: int, side: float, delta: float, state, sp: ScoreParams, backend=None):
    """The box with the half-size along axis k changed by ``delta`` (m) and the centre shifted so that only
    the face on ``side`` (+1 / -1) moves, by 2 * delta; the opposite face stays. Returns (center, half,
    gain) of the moved box; its gain comes from the backend's scoring loop, which visits only the points
    the box can reach (its values at every point are computed once, for the box a search ends with)."""
    c2 = c + (side * delta * axes[:, k]).to(c.dtype)[None]
    a2 = a.clone()
    a2[0, k] += delta
    backend = backend or backend_for("auto", pts.device)
    return c2, a2, float(backend.gains(pts, c2, a2, R, state, sp)[0])


def gain_of(values: torch.Tensor, state: torch.Tensor) -> float:
    """Inlier-count gain of one cuboid with per-point values f_OAI ``values`` over the current ``state``."""
    return float((combine(values, state) - state).sum())


def _refine_once(
    pts, c, a, R, values, state, gain, sp: ScoreParams, config: FitConfig, gen: torch.Generator, backend
):
    """Refine a cuboid on the points it newly explains with ``backend``; keep the result only if the gain
    holds."""
    inl = ((values >= 0.5) & (values > state)).nonzero().squeeze(1)
    if inl.numel() < config.min_set:
        return c, a, R, values, gain
    a_max = max(config.a_max, float(a.max()))  # a grown long slab keeps its length
    if inl.numel() > config.refine_max_points:
        inl = inl[torch.randperm(inl.numel(), generator=gen)[: config.refine_max_points].to(inl.device)]
    c2, a2, R2 = backend.refine(pts[inl], c[0], a[0], R[0], config.a_min, a_max)
    c2, a2, R2 = c2[None].to(c.dtype), a2[None].to(a.dtype), R2[None].to(R.dtype)
    v2 = values_one(pts, c2, a2, R2, sp, backend)
    g2 = gain_of(v2, state)
    if g2 >= gain - 0.005 * abs(gain):
        return c2, a2, R2, v2, g2
    return c, a, R, values, gain


def values_one(pts, c, a, R, sp: ScoreParams, backend: ScoringBackend | None = None) -> torch.Tensor:
    """f_OAI of one cuboid at every point (N,), float64, computed by ``backend`` (None: the default
    backend of the points' device)."""
    return (backend or backend_for("auto", pts.device)).values(pts, c, a, R, sp)[0]


def align_winner(
    pts, c, a, R, values, state, gain, sp: ScoreParams, config: FitConfig, alignment: Alignment, backend=None
):
    """Turn a (refined, grown) winner upright or onto the room's axes, re-fit its extents to the points it
    explains, and grow it again.

    Candidates: the nearest upright rotation (same yaw, :func:`upright_rotation`) and, for "manhattan",
    the nearest signed permutation of the room's axes (:func:`manhattan_rotation`; always taken by slabs,
    the walls, floor and ceiling of a room, and by other boxes unless the free yaw gains
    ``MANHATTAN_SLACK`` more). Each candidate keeps the winner's centre and sizes, its faces are
    moved onto the winner's new inliers (:func:`_refit_box`), and it grows like any winner.
    The best candidate replaces the winner when it keeps ``ALIGN_KEEP`` of its gain (a Manhattan one that
    does not falls back to the upright one); a slab of the room's shell (:func:`is_room_slab`) needs to keep
    only ``ROOM_KEEP``, and when its candidate falls short of that, the candidate is also tried on the plane
    most of its points lie on (:func:`_plane_sweep`) with its edges trimmed off anything seen beyond it
    (:func:`shrink_cuboid`), grown again, and the better one kept. A slab for which neither holds keeps
    its plane and is turned in it to upright edges (:func:`edge_to_vertical`) when that keeps
    ``ALIGN_KEEP`` of its gain.
    Returns (c, a, R, values, gain, kind) with kind "manhattan", "gravity", "tilted" (a slab in its own
    plane, edges turned upright) or "free" (kept as it was).
    """
    inl = ((values >= 0.5) & (values > state)).nonzero().squeeze(1)
    if inl.numel() < config.min_set:
        inl = (values >= 0.5).nonzero().squeeze(1)
    if inl.numel() < config.min_set:
        return c, a, R, values, gain, "free"
    p = pts[inl].double().cpu().numpy()
    r0 = R[0].double().cpu().numpy()
    c0, a0 = c[0].double().cpu().numpy(), a[0].double().cpu().numpy()

    all_pts = pts.double().cpu().numpy()
    room = is_room_slab(all_pts, c0, a0, r0, alignment.viewpoint, alignment.up)
    # the room's shell stands on the room's axes even where bent depth fits a tilted plane a little better
    keep = ROOM_KEEP if room else ALIGN_KEEP

    def place(on: np.ndarray, rot: np.ndarray):
        cn, an = _refit_box(on, c0, a0, rot, config.a_min)
        c2, a2, R2 = (torch.from_numpy(x)[None].to(device=c.device, dtype=c.dtype) for x in (cn, an, rot))
        v2 = values_one(pts, c2, a2, R2, sp, backend)
        return c2, a2, R2, v2, gain_of(v2, state)

    def grown(kind: str, c2, a2, R2, v2, g2):
        if g2 <= 0.0:  # nothing to grow from
            return kind, c2, a2, R2, v2, g2
        c3, a3, v3, g3 = grow_cuboid(pts, c2, a2, R2, state, g2, sp, config, backend)
        return kind, c3, a3, R2, v3, g3

    def candidate(kind: str, rot: np.ndarray):
        placed = place(p, rot)
        best = grown(kind, *placed)  # grow_cuboid works on copies: ``placed`` stays as it is
        if room and best[5] < keep * gain:
            # a wall in bent far depth: the plane most of its points lie on; a doorway or a mirror that
            # the turned wall now covers: its edges trimmed
            c2, a2, R2, v2, g2 = placed
            on = _plane_sweep(all_pts, state.cpu().numpy(), p, rot, _thin_of(rot, r0, a0))
            if on.shape[0] >= config.min_set:
                alt = place(on, rot)
                if alt[4] > g2:
                    c2, a2, R2, v2, g2 = alt
            c2, a2, v2, g2 = shrink_cuboid(pts, c2, a2, R2, state, g2, sp, config, backend)
            other = grown(kind, c2, a2, R2, v2, g2)
            if other[5] > best[5]:
                best = other
        return best

    if alignment.mode == "manhattan" and alignment.axes is not None:
        best = candidate("manhattan", manhattan_rotation(r0, alignment.axes, thin_axis(a0)))
        slab = thin_axis(best[2][0].cpu().numpy()) >= 0
        if not (slab and best[5] >= keep * gain):  # a slab on the room's axes needs no other
            upright = candidate("gravity", upright_rotation(r0, alignment.up))
            free_yaw_wins = upright[5] > best[5] + MANHATTAN_SLACK * abs(best[5])
            if (not slab and free_yaw_wins) or best[5] < keep * gain:
                best = upright  # off the room's axes, maybe still upright
    else:
        best = candidate("gravity", upright_rotation(r0, alignment.up))
    kind, c2, a2, R2, v2, g2 = best
    if g2 >= keep * gain:
        return c2, a2, R2, v2, g2, kind
    rot = edge_to_vertical(r0, thin_axis(a0), alignment)
    if rot is not None:
        kind, c2, a2, R2, v2, g2 = candidate("tilted", rot)
        if g2 >= ALIGN_KEEP * gain:
            return c2, a2, R2, v2, g2, kind
    return c, a, R, values, gain, "free"


def _thin_of(rot: np.ndarray, r0: np.ndarray, a0: np.ndarray) -> int:
    """The axis of ``rot`` nearest to the thickness axis of the slab with axes r0 and half-sizes a0."""
    n = r0[:, thin_axis(a0)]
    return int(np.argmax(np.abs(rot.T @ n)))


def _plane_sweep(
    points: np.ndarray, state: np.ndarray, own: np.ndarray, rot: np.ndarray, k: int
) -> np.ndarray:
    """The points of the best plane with normal ``rot[:, k]`` near a slab's own points ``own`` (M, 3): over
    the not yet explained points in the slab's footprint (its in-plane extent, 1st to 99th percentile)
    and within its depth range along the normal, the plane position holding the most points within
    :data:`FACE_BAND_M`, in 1 cm steps. A wall measured with a tilt (bent far depth) then stands where most
    of its points are, instead of at their median."""
    n = rot[:, k]
    i, j = [m for m in range(3) if m != k]
    s_own = own @ n
    lo, hi = np.percentile(s_own, [1.0, 99.0])
    uv_own = own @ rot[:, [i, j]]
    uv_lo, uv_hi = np.percentile(uv_own, [1.0, 99.0], axis=0)
    uv = points @ rot[:, [i, j]]
    sp = points @ n
    sel = (
        (state < 0.5)
        & (state >= 0.0)
        & np.all((uv >= uv_lo) & (uv <= uv_hi), axis=1)
        & (sp >= lo - FACE_BAND_M)
        & (sp <= hi + FACE_BAND_M)
    )
    cand, sv = points[sel], np.sort(sp[sel])
    if sv.size == 0:
        return own
    offsets = np.arange(lo, hi + 0.005, 0.01)
    counts = np.searchsorted(sv, offsets + FACE_BAND_M) - np.searchsorted(sv, offsets - FACE_BAND_M)
    best = offsets[int(np.argmax(counts))]
    return cand[np.abs(sp[sel] - best) < FACE_BAND_M]


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
    if viewpoint is not None and up is not None and abs(float(n @ up)) < 0.5:
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


#: A room slab is a floor or ceiling when its thickness axis is within this angle of gravity, a wall when
#: within it of horizontal; between the two it stays an object (a ramp, a tilted panel).
KIND_ANGLE_DEG = 20.0


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


def edge_to_vertical(rot: np.ndarray, k: int, alignment: Alignment) -> np.ndarray | None:
    """A slab's axes (3, 3) turned in its own plane (thickness axis k kept) so that one edge is as vertical
    as the plane allows; for a level slab (floor, table top) one edge along the room's first horizontal
    axis. A wall measured with a tilt (far Kinect depth bends) then stands with upright edges instead of
    as a rhombus. None when k < 0 (not a slab) or when there is no direction to turn to."""
    if k < 0:
        return None
    n = rot[:, k]
    target = alignment.up - (alignment.up @ n) * n
    if np.linalg.norm(target) < 0.3 and alignment.axes is not None:  # level: take a room axis
        h = alignment.axes[:, 1]
        target = h - (h @ n) * n
    norm = np.linalg.norm(target)
    if norm < 0.3:
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


def thin_axis(half: np.ndarray) -> int:
    """The thickness axis of a slab (wall, floor, ceiling, table top: its thinnest axis under a quarter of
    its middle one) with half-sizes ``half`` (3,), or -1 for a box that is not a slab."""
    order = np.argsort(half)
    return int(order[0]) if half[order[0]] < 0.25 * half[order[1]] else -1


def _refit_box(p: np.ndarray, center: np.ndarray, half: np.ndarray, rot: np.ndarray, a_min: float):
    """The box of the given half-sizes and centre turned to axes ``rot``, with its faces moved onto the
    points p (M, 3) it explains: a point lies on the face plane nearest to it when it is within
    ``FACE_BAND_M`` of it, and a face with points moves to their median; faces without points stay
    (growing moves them). A slab keeps its thickness, the face its points lie on goes to their median,
    and it spans the 1st to 99th percentile of them along its two long axes.
    Returns (center (3,), half (3,))."""
    local = (p - center) @ rot
    half = half.copy()
    slab = thin_axis(half)
    # distance of every point to each face plane, faces ordered (+x, -x, +y, -y, +z, -z): (M, 6)
    dist = np.abs(local[:, :, None] - np.stack([half, -half], axis=1)[None]).reshape(len(p), 6)
    nearest = dist.argmin(1)
    on_face = dist.min(1) < FACE_BAND_M
    lo, hi = -half.copy(), half.copy()
    mid = np.zeros(3)
    for k in range(3):
        if k == slab:  # the face the points lie on moves onto their median; the thickness stays behind it
            med = float(np.median(local[:, k]))
            mid[k] = med - np.sign(med) * half[k]
            continue
        if slab >= 0:  # a slab's edges have no points on them: it ends where its points end
            lo[k], hi[k] = np.percentile(local[:, k], [1.0, 99.0])
            mid[k], half[k] = 0.5 * (lo[k] + hi[k]), 0.5 * (hi[k] - lo[k])
            continue
        for side, bound in ((0, hi), (1, lo)):
            sel = on_face & (nearest == 2 * k + side)
            if sel.sum() >= 5:
                bound[k] = np.median(local[sel, k])
        if hi[k] - lo[k] < 2 * a_min:
            lo[k], hi[k] = -half[k], half[k]
        mid[k] = 0.5 * (lo[k] + hi[k])
        half[k] = 0.5 * (hi[k] - lo[k])
    return center + rot @ mid, np.maximum(half, a_min)

"""What happens to the winner of a step before it joins the set (paper Sec. 3.2 selects it as drawn; the
refinements here are ours): refinement on the points it newly explains, growing face by face to where its
surface ends, pulling faces in off points seen beyond it, and turning a slab to the tightest rectangle
around its points. Alignment to gravity or to the room's axes is :mod:`cuboidcli.fitting.align`.

Every function takes the winner as a :class:`~cuboidcli.fitting.box.Scored` (or a
:class:`~cuboidcli.fitting.box.Box`) and the step's :class:`~cuboidcli.fitting.box.StepContext`, whose
backend computes values, gains and refinements, and returns a new one; the inputs stay as they are.
"""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from cuboidcli.fitting.box import ROBUST_PERCENTILES, Box, Scored, StepContext, not_lines
from cuboidcli.fitting.refit import refit_box
from cuboidcli.geometry.arrays import as_kind, cast_like, copy, count, float64, numpy64, randperm

#: A slab turned to the tightest rectangle around its points (:func:`square_slab`) is kept when it gains
#: this share of what the solver's in-plane angle gains, both grown.
SQUARE_KEEP = 0.995
#: Face moves tried first when a slab thickens (m); the pull-back after growing trims an overshoot.
THICKEN_STEPS_M = (0.6, 0.3)
#: Steps (m) a face is pulled back by after growing, largest first, then ``FitConfig.grow_step_m``.
PULL_BACK_STEPS_M = (0.8, 0.4, 0.2)
#: In-plane angles tried for the tightest rectangle (radians).
SQUARE_ANGLES = np.deg2rad(np.arange(0.0, 90.0, 2.0))
#: A slab whose tightest rectangle is within this angle (radians) of its own is left as it is.
SQUARE_MIN_TURN = np.deg2rad(3.0)
#: A face move counts as a gain when it raises the inlier-count gain by more than this (inlier counts):
#: gains are float64 sums over thousands of points, and rounding must not move a face.
GAIN_EPS = 1e-6
#: A face with less room than this (m) left to its size cap does not grow.
MOVE_EPS_M = 1e-6
#: Pulling a face back keeps going while the gain stays within this share of the grown box's.
PULL_BACK_LOSS = 1e-3


def refine_winner(scored: Scored, ctx: StepContext) -> Scored:
    """Refine the winner on the points it newly explains, grow it face by face (:func:`grow_cuboid`), and
    refine the grown box again. Each result is kept only if the gain holds. A slab is also tried turned to
    the tightest rectangle around its points (:func:`square_slab`), grown and refined the same way. A box
    that refining or growing made a line (:func:`~cuboidcli.fitting.box.not_lines`) is not kept: the
    winner stays as it was drawn."""
    drawn = scored
    scored = _refine_once(scored, ctx)
    best = scored
    if ctx.config.grow_rounds >= 1:
        best = _grow_and_refine(scored, ctx)
        square = square_slab(scored, ctx)
        if square is not None:
            other = _grow_and_refine(ctx.score(square), ctx)
            if other.gain >= SQUARE_KEEP * best.gain:
                best = other
    return best if not_lines(best.box.half, ctx.sp.tau)[0] else drawn


def _grow_and_refine(scored: Scored, ctx: StepContext) -> Scored:
    grown = grow_cuboid(scored, ctx)
    if grown.gain <= scored.gain:
        return scored
    return _refine_once(grown, ctx)


def square_slab(scored: Scored, ctx: StepContext) -> Box | None:
    """A slab turned in its plane to the tightest rectangle around the points it newly explains, its
    extents re-fitted to them (:func:`~cuboidcli.fitting.refit.refit_box`): a six-point box on a table top
    or a cabinet front is at a random in-plane angle, which the inlier count cannot see but growing its
    edges and its thickness can. None for a box that is not a slab or is already turned that way."""
    box, config = scored.box, ctx.config
    k = box.thin_axis()
    if k < 0:
        return None
    inl = ctx.newly_explained(scored.values)
    if count(inl) < config.min_set:
        return None
    p = numpy64(ctx.points[inl])
    c0, a0, r0 = box.numpy()
    i, j = [m for m in range(3) if m != k]
    uv = (p - p.mean(0)) @ r0[:, [i, j]]
    cs, sn = np.cos(SQUARE_ANGLES), np.sin(SQUARE_ANGLES)
    x = uv @ np.stack([cs, sn])  # (M, angles): coordinates along the rotated first axis
    y = uv @ np.stack([-sn, cs])
    lo_hi = np.percentile(np.concatenate([x, y], 1), ROBUST_PERCENTILES, axis=0)
    extent = lo_hi[1] - lo_hi[0]
    n = len(SQUARE_ANGLES)
    best = SQUARE_ANGLES[int(np.argmin(extent[:n] * extent[n:]))]
    if min(best, np.pi / 2 - best) < SQUARE_MIN_TURN:  # already the tightest rectangle
        return None
    cs, sn = np.cos(best), np.sin(best)
    rot = r0.copy()
    rot[:, i], rot[:, j] = cs * r0[:, i] + sn * r0[:, j], -sn * r0[:, i] + cs * r0[:, j]
    cn, an = refit_box(p, c0, a0, rot, config.a_min)
    return Box.from_numpy(cn, an, rot, like=box.center)


def grow_cuboid(scored: Scored, ctx: StepContext) -> Scored:
    """Push each face of a cuboid outwards while the inlier-count gain rises (region growing).

    A minimal set of six points spans only part of a wall, a floor or a table top, and the solver's box
    ends at those points. Each round tries every face (for a slab, the faces across its thickness stay
    unless ``config.grow_thickness``): first a step of half the box's extent along that axis
    (at least ``config.grow_step_m``; a slab's thickness :data:`THICKEN_STEPS_M`), then a step of
    ``grow_step_m``; a move is kept when the gain rises by more than :data:`GAIN_EPS`, and a face that
    cannot move is done. Sizes stay within a_max (a slab's two long axes within ``config.slab_max_m``: a
    wall or a floor may be longer than 2 a_max). A big step may overshoot into space without points, so
    each face is then pulled back in steps of :data:`PULL_BACK_STEPS_M` ... ``grow_step_m`` m as long as
    the gain drops by less than :data:`PULL_BACK_LOSS`: the box ends where its surface ends. Returns the
    grown box with its values and gain (the input's box and gain when nothing grew) and the input's
    ``kind``."""
    config, box, gain = ctx.config, scored.box, scored.gain
    c, a, R = copy(box.center), copy(box.half), box.rotation
    grown = False
    axes = float64(R[0])
    slab_axis = box.thin_axis()
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
                if grow <= MOVE_EPS_M:
                    break
                moved_box, g2 = _move_face(Box(c, a, R), axes, k, sgn, grow, ctx)
                if g2 > gain + GAIN_EPS:
                    c, a, gain, grew, grown = moved_box.center, moved_box.half, g2, True, True
                    break
            if grew:
                moved = True
            else:
                done.add((k, sgn))
        if not moved:
            break
    if grown:
        # big steps may overshoot into space without points: pull each face back while no gain is lost
        floor = gain - PULL_BACK_LOSS * abs(gain)
        for k, sgn in faces:
            for step in PULL_BACK_STEPS_M + (config.grow_step_m,):
                while float(a[0, k]) - 0.5 * step >= config.a_min:
                    moved_box, g2 = _move_face(Box(c, a, R), axes, k, sgn, -0.5 * step, ctx)
                    if g2 < floor:
                        break
                    c, a, gain = moved_box.center, moved_box.half, g2
    out = Box(c, a, R)
    return Scored(out, ctx.values(out), gain, scored.kind)


def shrink_cuboid(scored: Scored, ctx: StepContext) -> Scored:
    """Pull faces of a cuboid inwards while the inlier-count gain rises: a slab turned onto the room's axes
    may cover points seen beyond it (through a doorway, in a mirror), which count against it, until its
    edges move in. A slab's thickness stays. Returns the box with its values and gain and the input's
    ``kind``."""
    config, box, gain = ctx.config, scored.box, scored.gain
    axes = float64(box.rotation[0])
    slab_axis = box.thin_axis()
    faces = [(k, sgn) for k in range(3) if k != slab_axis for sgn in (1.0, -1.0)]
    for _ in range(config.grow_rounds):
        moved = False
        for k, sgn in faces:  # the best of the steps, so that a big one does not cut into the surface
            moves = [
                _move_face(box, axes, k, sgn, -0.5 * step, ctx)
                for step in PULL_BACK_STEPS_M + (config.grow_step_m,)
                if float(box.half[0, k]) - 0.5 * step >= config.a_min
            ]
            best = max(moves, key=lambda m: m[1], default=None)
            if best is not None and best[1] > gain + GAIN_EPS:
                box, gain = best
                moved = True
        if not moved:
            break
    return Scored(box, ctx.values(box), gain, scored.kind)


def _move_face(box: Box, axes, k: int, side: float, delta: float, ctx: StepContext) -> tuple[Box, float]:
    """The box with the half-size along axis k changed by ``delta`` (m) and the centre shifted so that only
    the face on ``side`` (+1 / -1) moves, by 2 * delta; the opposite face stays. Returns the moved box and
    its gain, from the backend's scoring loop, which visits only the points the box can reach (its values
    at every point are computed once, for the box a search ends with)."""
    c2 = box.center + cast_like(side * delta * axes[:, k], box.center)[None]
    a2 = copy(box.half)
    a2[0, k] += delta
    moved = Box(c2, a2, box.rotation)
    return moved, ctx.gain(moved)


def _refine_once(scored: Scored, ctx: StepContext) -> Scored:
    """Refine a cuboid on the points it newly explains with the context's backend; keep the result only if
    the gain drops by at most ``config.refine_keep`` of it."""
    config, box = ctx.config, scored.box
    inl = ctx.newly_explained(scored.values)
    if count(inl) < config.min_set:
        return scored
    a_max = max(config.a_max, float(box.half.max()))  # a grown long slab keeps its length
    if count(inl) > config.refine_max_points:
        pick = randperm(count(inl), ctx.generator)[: config.refine_max_points]
        inl = inl[as_kind(pick, inl)]
    c, a, R = box.center, box.half, box.rotation
    c2, a2, R2 = ctx.backend.refine(
        ctx.points[inl], c[0], a[0], R[0], config.a_min, a_max, config.refine_iters, config.refine_lr
    )
    refined = Box(cast_like(c2[None], c), cast_like(a2[None], a), cast_like(R2[None], R))
    out = replace(ctx.score(refined), kind=scored.kind)
    if out.gain >= scored.gain - config.refine_keep * abs(scored.gain):
        return out
    return scored

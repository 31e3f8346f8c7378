"""The value of one point for one cuboid in a room, and what a block of points can add at most.

The numba helpers of :mod:`cuboidcli.geometry.room`: a point's value in each visibility (:func:`room_value`),
the tests that decide which blocks of points a cuboid reaches (:func:`meets` along the world's axes,
:func:`meets_local` along the cuboid's), and the most any point of a block can add (:func:`at_most`), which
lets a hypothesis be abandoned before the points of a block that can only lose are scored.
"""

from __future__ import annotations

from numba import njit

from cuboidcli.geometry.inlier import f_inlier, occluding_value, pair_value, to_local


@njit(cache=True, inline="always")
def room_value(l0, l1, l2, a0, a1, a2, c0, c1, c2, beta, inv_tau, tau_c, slope, offset, cutoff, mode):
    """The value of one point (local l) for one cuboid (half-sizes a; its viewpoint c for "views")."""
    if mode == 0:
        if apart(l0, l1, l2, a0, a1, a2, c0, c1, c2, cutoff):
            return 0.0
        oai = True
        args = (beta, inv_tau, tau_c, slope, offset, cutoff, oai)
        v = pair_value(l0, l1, l2, a0, a1, a2, c0, c1, c2, *args)
        # A viewpoint inside the cuboid: the whole line of sight from it to the cuboid's surface was seen
        # empty, yet the solid box claims it (a camera is never inside furniture, and a box around the
        # room's interior would swallow every wall from within). Penalised like a side the point hides
        # behind, by the viewpoint's depth inside the box.
        m = min(a0 - abs(c0), min(a1 - abs(c1), a2 - abs(c2)))
        if m > 0:
            inside = occluding_value(m * m, beta, inv_tau, tau_c, slope, offset, cutoff)
            if inside < 0:
                v = min(v, inside)
        return v
    q0 = abs(l0) - a0
    q1 = abs(l1) - a1
    q2 = abs(l2) - a2
    if mode == 1 and q0 < 0 and q1 < 0 and q2 < 0:
        m = min(-q0, min(-q1, -q2))
        return occluding_value(m * m, beta, inv_tau, tau_c, slope, offset, cutoff)
    e0 = q0 * q0 if q0 > 0 else 0.0
    e1 = q1 * q1 if q1 > 0 else 0.0
    e2 = q2 * q2 if q2 > 0 else 0.0
    m = min(-q0, min(-q1, -q2))
    d2 = e0 + e1 + e2 + (m * m if m > 0 else 0.0)
    return f_inlier(d2, beta, inv_tau) if d2 < cutoff else 0.0


@njit(cache=True, inline="always")
def apart(l0, l1, l2, a0, a1, a2, c0, c1, c2, cutoff):
    """Whether a point (local l) lies beyond the inlier cutoff of a cuboid and on the same side of one of
    its faces' planes as its viewpoint (local c): the line of sight cannot meet the box and the viewpoint
    is outside it, so the point's value is exactly 0. Most points a hypothesis visits are such; this
    spares them the line-of-sight test (:func:`~cuboidcli.geometry.inlier.slab_occlusion` finds no side
    on such a segment: both its crossings of that axis's slab lie outside (0, 1))."""
    if not (
        (l0 > a0 and c0 > a0) or (l0 < -a0 and c0 < -a0)
        or (l1 > a1 and c1 > a1) or (l1 < -a1 and c1 < -a1)
        or (l2 > a2 and c2 > a2) or (l2 < -a2 and c2 < -a2)
    ):  # fmt: skip
        return False
    q0, q1, q2 = abs(l0) - a0, abs(l1) - a1, abs(l2) - a2
    # outside the box on that axis, so the squared distance is the outside excess alone
    d2 = (q0 * q0 if q0 > 0 else 0.0) + (q1 * q1 if q1 > 0 else 0.0) + (q2 * q2 if q2 > 0 else 0.0)
    return d2 >= cutoff


@njit(cache=True, inline="always")
def extent(R, a0, a1, a2):
    """Half-extents of a cuboid's axis-aligned bounding box."""
    return (
        abs(R[0, 0]) * a0 + abs(R[0, 1]) * a1 + abs(R[0, 2]) * a2,
        abs(R[1, 0]) * a0 + abs(R[1, 1]) * a1 + abs(R[1, 2]) * a2,
        abs(R[2, 0]) * a0 + abs(R[2, 1]) * a1 + abs(R[2, 2]) * a2,
    )


@njit(cache=True, inline="always")
def meets(lo, hi, b, c0, c1, c2, e0, e1, e2):
    """Does the box [lo[b], hi[b]] meet the box centred at c with half-extents e?"""
    return (
        lo[b, 0] <= c0 + e0
        and hi[b, 0] >= c0 - e0
        and lo[b, 1] <= c1 + e1
        and hi[b, 1] >= c1 - e1
        and lo[b, 2] <= c2 + e2
        and hi[b, 2] >= c2 - e2
    )


@njit(cache=True, inline="always")
def block_local(lo, hi, b, t0, t1, t2, R):
    """The box [lo[b], hi[b]] in a cuboid's frame (centre t, axes R): its centre's offset along each of
    the cuboid's axes, and its half-extent along each."""
    h0, h1, h2 = 0.5 * (hi[b, 0] - lo[b, 0]), 0.5 * (hi[b, 1] - lo[b, 1]), 0.5 * (hi[b, 2] - lo[b, 2])
    m0, m1, m2 = 0.5 * (lo[b, 0] + hi[b, 0]), 0.5 * (lo[b, 1] + hi[b, 1]), 0.5 * (lo[b, 2] + hi[b, 2])
    l0, l1, l2 = to_local(m0 - t0, m1 - t1, m2 - t2, R)
    return (
        abs(l0), abs(l1), abs(l2),
        abs(R[0, 0]) * h0 + abs(R[1, 0]) * h1 + abs(R[2, 0]) * h2,
        abs(R[0, 1]) * h0 + abs(R[1, 1]) * h1 + abs(R[2, 1]) * h2,
        abs(R[0, 2]) * h0 + abs(R[1, 2]) * h1 + abs(R[2, 2]) * h2,
    )  # fmt: skip


@njit(cache=True, inline="always")
def meets_local(lo, hi, b, t0, t1, t2, R, a0, a1, a2):
    """Does the box [lo[b], hi[b]] meet the cuboid, tested along the cuboid's axes?"""
    d0, d1, d2, x0, x1, x2 = block_local(lo, hi, b, t0, t1, t2, R)
    return d0 <= a0 + x0 and d1 <= a1 + x1 and d2 <= a2 + x2


@njit(cache=True, inline="always")
def at_most(lo, hi, view_lo, view_hi, b, t0, t1, t2, R, a0, a1, a2, params, mode, near):
    """The most the value of any point of block b can be for a cuboid: 1 (f_I) unless the block can only
    lose. Then 0, or below 0 where it is known:

    - ``near`` False: the block is reached by lines of sight alone, its points lie beyond the inlier margin.
    - All its points deeper inside the cuboid than the inlier margin, by m: in "inside" visibility each
      counts f_IO(m^2); in "views", a point seen from outside the cuboid is hidden by the side its line of
      sight leaves through, at least m from it, so it counts at most f_IO(m^2) (f_IO falls with depth).
    - In "views", every viewpoint of the block deeper inside than sqrt(tau), by m: each point counts at most
      f_IO(m^2) < 0, the penalty of a viewpoint inside the box.

    Bounds below 0 are loosened by a millionth against rounding."""
    beta, inv_tau, tau_c, slope, offset, cutoff = params
    most = 0.0
    deep = False
    if near:
        d0, d1, d2, x0, x1, x2 = block_local(lo, hi, b, t0, t1, t2, R)
        depth = min(a0 - d0 - x0, min(a1 - d1 - x1, a2 - d2 - x2))
        deep = depth > 0 and depth * depth > cutoff
        if not deep:
            most = 1.0
        elif mode == 1:
            most = occluding_value(depth * depth, beta, inv_tau, tau_c, slope, offset, cutoff)
    if mode == 0:
        c0, c1, c2, y0, y1, y2 = block_local(view_lo, view_hi, b, t0, t1, t2, R)
        seen_in = min(a0 - c0 - y0, min(a1 - c1 - y1, a2 - c2 - y2))
        if seen_in > 0 and seen_in * seen_in > 1.0 / inv_tau:
            most = min(most, occluding_value(seen_in * seen_in, beta, inv_tau, tau_c, slope, offset, cutoff))
        elif deep and (c0 - y0 > a0 or c1 - y1 > a1 or c2 - y2 > a2):
            most = occluding_value(depth * depth, beta, inv_tau, tau_c, slope, offset, cutoff)
    return most * (1.0 - 1e-6) if most < 0 else most


@njit(cache=True, inline="always")
def point_value(points, views, i, t0, t1, t2, R, a0, a1, a2, params, mode):
    beta, inv_tau, tau_c, slope, offset, cutoff = params
    l0, l1, l2 = to_local(points[i, 0] - t0, points[i, 1] - t1, points[i, 2] - t2, R)
    c0 = c1 = c2 = 0.0
    if mode == 0:
        c0, c1, c2 = to_local(views[i, 0] - t0, views[i, 1] - t1, views[i, 2] - t2, R)
    return room_value(l0, l1, l2, a0, a1, a2, c0, c1, c2, beta, inv_tau, tau_c, slope, offset, cutoff, mode)

"""Doors that lie in their wall's plane, told from the wall by their colour.

A closed door stands within a few centimetres of its wall's plane, so the fit takes its points for the
wall; the grouping never sees them. What gives it away is its colour: a door's leaf is painted or stained
otherwise than the wall on both sides of it (a white wall, a wooden door). In a band
:data:`LEAF_BAND_M` (m) either side of each upright wall cuboid's face (the median of its inliers), the
points are cut into columns :data:`LEAF_CELL_M` wide along the wall. A column speaks for itself when its
points between :data:`LEAF_BODY_M` (m) above the floor fill at least :data:`LEAF_FILL` of its cells; its
colour is their median. Neighbouring columns whose colours stay within :data:`LEAF_ALIKE` (RGB, 0-255) of
the run's median form a run (a column or two without points, a handle's shadow, does not end it). A run is
a door's leaf when:

- it is a door wide (:data:`LEAF_WIDTH_M`);
- the wall :data:`LEAF_SIDE_M` (m) beyond each of its ends (past the frame) is seen, on both sides, and
  each side's colour differs from the run's by at least :data:`LEAF_CONTRAST`: a door in a corner, with
  wall on one side only, is not told from a stretch of wall beside a cupboard or a wall in two paints;
- its colour reaches :data:`LEAF_TOP_M` (m) above the floor and stops below the upper bound: a door ends
  at its frame's top, a stretch of wall in another paint goes on to the ceiling;
- its colour comes down to within :data:`LEAF_FOOT_M` of the floor: a screen or a picture on a wall does
  not.

Its box stands on the floor, spans the run along the wall and reaches the top of the run's colour;
:data:`LEAF_DEPTH_M` deep, centred on the wall's face (ScanNet's door boxes are 13-40 cm deep: frame,
leaf and the opening through the wall). A door seen in the planes of two wall cuboids is kept once.

On the 10 real ScanNet scans (the saved fits of seeds 0-4, grouped again), recall at IoU 0.25 went from
64.2 to 67.5 % (the five seeds' mean) at a precision of 78.0 -> 77.8 %, and on the sequences rendered
from them from 58.6 to 60.4 % at 76.7 % before and after (docs/scenes.md); 25 of the 26 doors it found
on the scans are in one apartment. A white door in a white wall is not found. Numpy, float64.
"""

from __future__ import annotations

import math

import numpy as np

from cuboidcli.cuboid import Cuboid

#: The band either side of a wall's face (m) whose points may be a door's.
LEAF_BAND_M = 0.06
#: Columns along the wall and cells up it (m).
LEAF_CELL_M = 0.05
#: A column's colour and fill come from its points this high above the floor (m): above a skirting board,
#: below the top of a door that a scan stopping at 1.5-2 m still sees.
LEAF_BODY_M = (0.2, 1.7)
#: Share of a column's cells in :data:`LEAF_BODY_M` that hold a point for the column to count.
LEAF_FILL = 0.4
#: Columns within this colour distance (RGB, 0-255) of the run's median belong to it.
LEAF_ALIKE = 35.0
#: Columns without points a run may bridge.
LEAF_GAP = 2
#: A door's width along its wall (m).
LEAF_WIDTH_M = (0.6, 1.6)
#: The wall beside a door: this far (m) beyond the run's ends, past the door's frame.
LEAF_SIDE_M = (0.1, 0.4)
#: Each side's colour differs from the run's by at least this much (RGB, 0-255).
LEAF_CONTRAST = 45.0
#: The run's colour reaches at least the first and at most the second height above the floor (m).
LEAF_TOP_M = (1.5, 2.25)
#: The door's box is this deep across its wall (m), centred on the wall's face.
LEAF_DEPTH_M = 0.2
#: The door's top is this percentile of the heights of the run's points within :data:`LEAF_ALIKE` of its
#: colour.
LEAF_TOP_PERCENTILE = 97.0
#: A door reaches the floor: the heights' percentile opposite :data:`LEAF_TOP_PERCENTILE` is at most this
#: high (m). On the saved fits of seeds 0-4 the doors found reach 0.02-0.34 m, a refrigerator's door in a
#: wall's plane 0.41 m; a screen or a picture on a wall starts higher still.
LEAF_FOOT_M = 0.4
#: The band reaches this high above the floor (m), and this far beyond the wall's inliers along it (m).
LEAF_REACH_M = (2.4, 0.3)
#: Two doors whose centres are closer than this (m) are one door seen in two walls' planes.
LEAF_SAME_M = 0.3
#: A wall cuboid needs this many inliers, and its band this many points, to be looked at.
LEAF_MIN_POINTS = 50


def _column_colours(col: np.ndarray, row: np.ndarray, body: np.ndarray, colors: np.ndarray, ncol: int):
    """Each column's median colour (NaN where it has under 3 points in the body) and the share of the body's
    rows its points fill."""
    nrows = max(1, int(round((LEAF_BODY_M[1] - LEAF_BODY_M[0]) / LEAF_CELL_M)))
    med = np.full((ncol, 3), np.nan)
    fill = np.zeros(ncol)
    for k in np.unique(col[body]):
        m = body & (col == k)
        if m.sum() >= 3:
            med[k] = np.median(colors[m], axis=0)
            fill[k] = len(np.unique(row[m])) / nrows
    return med, fill


def _runs(med: np.ndarray, seen: np.ndarray) -> list[list[int]]:
    """Runs of seen columns alike in colour, each a list of its columns, left to right."""
    runs, k, n = [], 0, len(seen)
    while k < n:
        if not seen[k]:
            k += 1
            continue
        run, j, gap = [k], k + 1, 0
        while j < n:
            if seen[j] and np.linalg.norm(med[j] - np.median(med[run], axis=0)) <= LEAF_ALIKE:
                run, gap = run + [j], 0
            elif not seen[j] and gap < LEAF_GAP:
                gap += 1
            else:
                break
            j += 1
        runs.append(run)
        k = run[-1] + 1
    return runs


def _sides_differ(run: list[int], med: np.ndarray, seen: np.ndarray, colour: np.ndarray) -> bool:
    """Whether the wall beside ``run`` is seen on both sides and differs in colour from ``colour`` there."""
    near, far = (int(round(v / LEAF_CELL_M)) for v in LEAF_SIDE_M)
    for cols in (range(run[0] - far, run[0] - near + 1), range(run[-1] + near, run[-1] + far + 1)):
        side = [med[q] for q in cols if 0 <= q < len(seen) and seen[q]]
        if len(side) < 2 or np.linalg.norm(np.median(side, axis=0) - colour) < LEAF_CONTRAST:
            return False
    return True


def door_leaves(
    level: np.ndarray,
    labels: np.ndarray,
    cuboids: list[Cuboid],
    R: np.ndarray,
    under: np.ndarray,
    colors: np.ndarray | None,
    known: list[Cuboid] | tuple[Cuboid, ...] = (),
) -> list[tuple[int, Cuboid, np.ndarray, np.ndarray, np.ndarray]]:
    """The doors in the planes of a room's wall cuboids (module docstring).

    ``level`` (M, 3) are the fitting points in the room's level frame (``R`` turns it to the world, its z
    the room's up), ``labels`` (M,) their cuboid, ``under`` (M,) the floor's height under each point and
    ``colors`` (M, 3) their colours, 0-255 (None: no door is found). Each door as (its wall cuboid's index,
    its upright box in the world frame, its points in the box's level frame, and the box's lower and upper
    corners there), as :func:`~cuboidcli.fitting.doors.door_walls` gives them; none within
    :data:`LEAF_SAME_M` of the centre of a door already ``known``."""
    if colors is None or not len(level):
        return []
    colors = np.asarray(colors, dtype=np.float64).reshape(-1, 3)
    height = level[:, 2] - under
    found: list[tuple[int, Cuboid, np.ndarray, np.ndarray, np.ndarray]] = []
    for i, c in enumerate(cuboids):
        inliers = labels == i
        axes = R.T @ c.rotation
        k = int(np.argmin(c.half_size))
        if c.kind != "wall" or abs(axes[2, k]) > 0.2 or inliers.sum() < LEAF_MIN_POINTS:
            continue
        normal = axes[:2, k] / np.linalg.norm(axes[:2, k])
        theta = math.atan2(normal[0], -normal[1])  # along the wall: the normal turned a quarter
        cos, sin = math.cos(theta), math.sin(theta)
        turn = np.array([[cos, -sin, 0.0], [sin, cos, 0.0], [0.0, 0.0, 1.0]])
        local = level @ turn  # x along the wall, y across it, z up
        face = float(np.median(local[inliers, 1]))
        lo_u, hi_u = np.percentile(local[inliers, 0], [1.0, 99.0]) + np.array([-1.0, 1.0]) * LEAF_REACH_M[1]
        band = np.flatnonzero(
            (np.abs(local[:, 1] - face) <= LEAF_BAND_M)
            & (local[:, 0] >= lo_u)
            & (local[:, 0] <= hi_u)
            & (height >= 0.0)
            & (height <= LEAF_REACH_M[0])
        )
        if len(band) < LEAF_MIN_POINTS:
            continue
        col = ((local[band, 0] - lo_u) / LEAF_CELL_M).astype(np.int64)
        row = (height[band] / LEAF_CELL_M).astype(np.int64)
        body = (height[band] >= LEAF_BODY_M[0]) & (height[band] <= LEAF_BODY_M[1])
        med, fill = _column_colours(col, row, body, colors[band], int(col.max()) + 1)
        seen = fill >= LEAF_FILL
        for run in _runs(med, seen):
            width = (run[-1] - run[0] + 1) * LEAF_CELL_M
            colour = np.median(med[run], axis=0)
            if not LEAF_WIDTH_M[0] <= width <= LEAF_WIDTH_M[1] or not _sides_differ(run, med, seen, colour):
                continue
            members = band[(col >= run[0]) & (col <= run[-1])]
            alike = members[np.linalg.norm(colors[members] - colour, axis=1) <= LEAF_ALIKE]
            if len(alike) < LEAF_MIN_POINTS:
                continue
            top, foot = np.percentile(height[alike], [LEAF_TOP_PERCENTILE, 100.0 - LEAF_TOP_PERCENTILE])
            if not LEAF_TOP_M[0] <= top <= LEAF_TOP_M[1] or foot > LEAF_FOOT_M:
                continue
            top = float(top)
            members = members[height[members] <= top]
            floor_z = float(np.median(under[members]))
            lo = np.array([lo_u + run[0] * LEAF_CELL_M, face - LEAF_DEPTH_M / 2, floor_z])
            hi = np.array([lo_u + (run[-1] + 1) * LEAF_CELL_M, face + LEAF_DEPTH_M / 2, floor_z + top])
            rotation = R @ turn
            box = Cuboid(rotation @ ((lo + hi) / 2), (hi - lo) / 2, rotation, kind="object")
            found.append((i, box, local[members], lo, hi))
    kept: list[tuple[int, Cuboid, np.ndarray, np.ndarray, np.ndarray]] = []
    centres = [b.center for b in known]
    for door in sorted(found, key=lambda d: -len(d[2])):
        if all(np.linalg.norm(door[1].center - other) > LEAF_SAME_M for other in centres):
            kept.append(door)
            centres.append(door[1].center)
    return kept

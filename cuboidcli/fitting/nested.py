"""Groups nested in another group's box: one object's pieces join, two objects' stay apart.

The grouping (:mod:`cuboidcli.fitting.objects`) grows one group from each cuboid's inliers, so one piece of
furniture often starts as several groups: a chair's seat and its back, a table's top and the frame under
it. When the box of a smaller group lies almost wholly (:data:`~cuboidcli.fitting.objects.MERGE_OVERLAP`)
inside a larger group's box, the two are one object. But a chair pushed under a table, a stool under a
counter or a box on a shelf lies inside the larger box as well, and joining them makes one box over two
objects. What tells the two cases apart in a scan is colour: the pieces of one object are mostly made of
one material, while a chair under a table, or a window's sill behind a cabinet, differs from it. A nested
group joins only when the median colours of the two groups lie within :data:`MERGE_COLOUR` of each other
(RGB, 0-255); without colours (a bare cloud) any nested group joins.

A nested group of fewer than :data:`OWN_POINTS` fitting points joins whatever its colour.

On the 10 real ScanNet scans (the saved fits of seeds 0-2, grouped again): recall at IoU 0.25 61.7 / 62.4 /
61.7 -> 61.7 / 63.8 / 61.7 %, precision 76.3 / 74.4 / 73.5 -> 76.6 / 74.0 / 73.9 %, 0.5-1.3 more object
boxes a scan; the sequences rendered from them: recall 55.4 / 57.1 / 53.6 -> 56.2 / 57.1 / 53.6 %,
precision 77.2 / 73.6 / 71.7 -> 77.5 / 73.9 / 72.0 % (docs/scenes.md). Without the bound on the smaller
group's points precision rose further (76.9 / 74.9 / 74.0 %, sequences 78.0 / 74.3 / 72.4 %), but by
fragments: 2-4 more boxes a scan, most of them scraps of 20-50 points on one labelled object (a cushion
of a sofa, the shadowed side of a cabinet), which a user counts as one object broken up.

A smaller group that touches a larger group's box from below (:func:`join_under`) is its part too: a chair's
base under its seat, the frame under a table's top, when the scan saw too few points between them for the
two to touch. Standing on the floor under a larger box's bottom and touching it means being held up by it.
"""

from __future__ import annotations

from collections.abc import Callable

import numpy as np

#: Two nested groups whose median colours lie further apart than this (Euclidean, RGB 0-255) stay apart.
MERGE_COLOUR = 40.0
#: ... when the smaller holds at least this many fitting points: a smaller piece of another colour (a
#: cushion, a handle, a shadowed side) is a part of the larger object, and kept apart it is a fragment.
OWN_POINTS = 100

#: A group joins a larger one (:func:`join_under`) when its top lies within this distance (m) of the larger
#: box's bottom, below or above it, and its bottom lies lower than that box's bottom ...
UNDER_GAP_M = 0.1
#: ... and at least this share of its footprint lies under the larger box's footprint. On the 10 real
#: ScanNet scans (the saved fits of seeds 0-4, grouped again) the object boxes fell from 1,714 to 1,624: 71
#: fewer fragments of one labelled object, 19 fewer boxes on none, 9 more labelled boxes matched (recall at
#: IoU 0.25 63.6 -> 64.8 %); precision, the share of boxes on one labelled object, 74.2 -> 73.9 %, as the
#: fragments counted in it. The sequences rendered from them: 63 boxes fewer, recall 57.5 -> 57.7 %,
#: precision 74.7 -> 74.2 % (docs/scenes.md). With 5 cm instead of 10 fewer pieces join (recall 64.0 %).
UNDER_FOOTPRINT = 0.5

Box = tuple[list[float], list[float], float]


def join_nested(
    groups: dict[int, np.ndarray],
    box_of: Callable[[int, int], Box],
    forget: Callable[[int, int], None],
    overlap: float,
    colors: np.ndarray | None = None,
) -> None:
    """Join, in place, each group of ``groups`` ({group: indices of its points}) whose box lies at least
    ``overlap`` (share of the smaller box's volume) inside a larger group's box, in that group's heading
    (``box_of(g, h)``: (lo, hi, volume) of group g's box in group h's heading), when the median colours of
    their points (``colors`` (N, 3), 0-255, or None: no colours, any nested group joins) lie within
    :data:`MERGE_COLOUR`, or when the smaller holds fewer than :data:`OWN_POINTS` points. Largest groups
    first, until nothing joins; ``forget(a, b)`` is called after b joined a (the boxes of both changed)."""
    colours: dict[int, np.ndarray] = {}  # each group's median colour, kept until the group changes

    def same_colour(a: int, b: int) -> bool:
        if colors is None or min(len(groups[a]), len(groups[b])) < OWN_POINTS:
            return True
        for g in (a, b):
            if g not in colours:
                colours[g] = np.median(colors[groups[g]], axis=0)
        return float(np.linalg.norm(colours[a] - colours[b])) <= MERGE_COLOUR

    merged = True
    while merged:
        merged = False
        order = sorted(groups, key=lambda g: -len(groups[g]))
        for i, a in enumerate(order):
            for b in order[i + 1 :]:
                lo_a, hi_a, vol_a = box_of(a, a)
                lo_b, hi_b, vol_b = box_of(b, a)  # the smaller group in a's heading
                common = 1.0
                for k in range(3):
                    common *= max(min(hi_a[k], hi_b[k]) - max(lo_a[k], lo_b[k]), 0.0)
                if common >= overlap * min(vol_a, vol_b) and same_colour(a, b):
                    groups[a] = np.concatenate([groups[a], groups.pop(b)])
                    colours.pop(a, None)
                    forget(a, b)
                    merged = True
                    break
            if merged:
                break


def join_under(
    groups: dict[int, np.ndarray], box_of: Callable[[int, int], Box], forget: Callable[[int, int], None]
) -> None:
    """Join, in place, each group of ``groups`` whose box touches a larger group's box from below: its top
    within :data:`UNDER_GAP_M` of that box's bottom, its bottom lower than it, and at least
    :data:`UNDER_FOOTPRINT` of its footprint under that box's (``box_of`` and ``forget`` as in
    :func:`join_nested`; larger means the larger box). Largest first, until nothing joins."""
    merged = True
    while merged:
        merged = False
        order = sorted(groups, key=lambda g: -box_of(g, g)[2])
        for i, a in enumerate(order):
            lo_a, hi_a, _ = box_of(a, a)
            for b in order[i + 1 :]:
                lo_b, hi_b, _ = box_of(b, a)  # the smaller group in a's heading
                if lo_b[2] >= lo_a[2] or abs(hi_b[2] - lo_a[2]) > UNDER_GAP_M:
                    continue
                common = 1.0
                for k in range(2):
                    common *= max(min(hi_a[k], hi_b[k]) - max(lo_a[k], lo_b[k]), 0.0)
                if common >= UNDER_FOOTPRINT * (hi_b[0] - lo_b[0]) * (hi_b[1] - lo_b[1]):
                    groups[a] = np.concatenate([groups[a], groups.pop(b)])
                    forget(a, b)
                    merged = True
                    break
            if merged:
                break


def rests_on(g: int, groups: dict[int, np.ndarray], box_of: Callable[[int, int], Box]) -> bool:
    """Whether group ``g``'s box rests on another group's box of ``groups``: its bottom within
    :data:`UNDER_GAP_M` of that box's top and at least :data:`UNDER_FOOTPRINT` of its footprint over it
    (``box_of`` as in :func:`join_nested`): a screen on a desk stands, it does not hang."""
    lo_g, hi_g, _ = box_of(g, g)
    area = (hi_g[0] - lo_g[0]) * (hi_g[1] - lo_g[1])
    for b in groups:
        if b == g:
            continue
        lo_b, hi_b, _ = box_of(b, g)
        if abs(hi_b[2] - lo_g[2]) > UNDER_GAP_M:
            continue
        common = 1.0
        for k in range(2):
            common *= max(min(hi_g[k], hi_b[k]) - max(lo_g[k], lo_b[k]), 0.0)
        if common >= UNDER_FOOTPRINT * area:
            return True
    return False

"""The segment filters of geometry/lines.py at their exact edges: the border bands end alike on all four
sides, and a segment exactly as long as the shortest kept one is kept ("shorter than this ... dropped")."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.geometry import lines as lines_mod


@pytest.mark.parametrize(("width", "height"), [(640, 480), (300, 500), (400, 400)])
def test_the_border_bands_end_alike_on_every_side(width, height):
    # a segment whose ends lie exactly at the band's inner edge (BORDER_FRACTION of the short side from the
    # outermost pixel centres, 0 and width - 1 / height - 1), parallel to the side: every side says the same
    m = lines_mod.BORDER_FRACTION * min(width, height)
    xs, ys = (width - 1) / 2, (height - 1) / 2
    segs = np.array(
        [
            [m, ys - 40, m, ys + 40],  # left
            [width - 1 - m, ys - 40, width - 1 - m, ys + 40],  # right
            [xs - 40, m, xs + 40, m],  # top
            [xs - 40, height - 1 - m, xs + 40, height - 1 - m],  # bottom
        ]
    )
    along = lines_mod._along_border(segs, width, height)
    assert len(set(along.tolist())) == 1, along
    # one end exactly at the edge, the other inside the band: as the segment with both ends at the edge
    inside = np.array(
        [
            [m, ys, m / 2, ys + 40],
            [width - 1 - m, ys, width - 1 - m / 2, ys + 40],
            [xs, m, xs + 40, m / 2],
            [xs, height - 1 - m, xs + 40, height - 1 - m / 2],
        ]
    )
    assert np.array_equal(lines_mod._along_border(inside, width, height), along)


def test_a_segment_exactly_as_long_as_the_shortest_kept_is_kept(monkeypatch):
    # a 640 x 480 image (diagonal 800 px) and a fraction 1/16 (exact in binary): segments shorter than
    # 50 px are dropped, one of 50 px (a 3-4-5 triangle: 30 across, 40 down) is kept, one of 49.9 px not
    found = np.array(
        [
            [100.0, 100.0, 130.0, 140.0],  # 50 px
            [300.0, 200.0, 349.9, 200.0],  # 49.9 px
            [200.0, 300.0, 200.0, 380.0],  # 80 px
        ],
        np.float32,
    )
    monkeypatch.setattr(lines_mod, "_lsd", lambda grey: found)
    img = np.full((480, 640), 40, np.uint8)
    segs = lines_mod.detect_segments(img, min_length_fraction=1 / 16)
    np.testing.assert_array_equal(segs, found[[2, 0]].astype(np.float64))  # longest first

"""The down direction from the depth and the photo's lines (geometry/down.py): a photo's lines come first,
a depth map's own estimate is kept unless unsure, agreement is named, and neither sure gives one note."""

from __future__ import annotations

import dataclasses
import math
from dataclasses import replace

import numpy as np
import pytest

from cuboidcli.geometry.down import AGREE_DEG, DEPTH_SURE, LINES_SURE, angle_deg, combine_down
from cuboidcli.geometry.gravity import Gravity
from cuboidcli.geometry.vanishing import estimate_from_lines
from tests.geometry.test_vanishing import render_room


def _tilted(deg: float) -> np.ndarray:
    """Down (0, 1, 0) turned by ``deg`` about the camera's x axis."""
    a = math.radians(deg)
    return np.array([0.0, math.cos(a), math.sin(a)])


@pytest.fixture(scope="module")
def lines():
    img, _ = render_room(500.0, -15.0, 0.0, 30.0)
    est = estimate_from_lines(img)
    assert est is not None and est.down_confidence >= LINES_SURE
    return est


def _lines(est, down, confidence):
    axes = np.stack([-down, [1.0, 0.0, 0.0], np.cross(-down, [1.0, 0.0, 0.0])], axis=1)
    return replace(est, down=down, down_confidence=confidence, axes=axes)


def _depth(down, confidence):
    frame = np.stack([-down, [1.0, 0.0, 0.0], np.cross(-down, [1.0, 0.0, 0.0])], axis=1)
    return Gravity(down=down, source="estimated", confidence=confidence, frame=frame, support=(0.1, 0.1, 0.1))


def test_a_photo_takes_its_confident_lines_over_the_predicted_depth(lines):
    depth = _depth(_tilted(30.0), 0.5)  # sure, but 30 degrees off: predicted depth leans
    line = _lines(lines, _tilted(0.0), 0.8)
    choice = combine_down(depth, line, lines_first=True)
    assert choice.sure and choice.note == ""
    g = choice.gravity
    assert g.source == "photo lines" and np.array_equal(g.down, line.down) and g.confidence == 0.8
    assert np.array_equal(g.frame, line.axes) and g.lines_deg == pytest.approx(30.0)
    # agreeing: both named, the lines' direction
    near = combine_down(_depth(_tilted(AGREE_DEG - 1), 0.05), line, lines_first=True)
    assert near.gravity.source == "lines and depth" and np.array_equal(near.gravity.down, line.down)
    assert near.sure and near.note == ""
    # unsure lines: the sure depth alone
    weak = combine_down(depth, _lines(lines, _tilted(0.0), 0.1), lines_first=True)
    assert weak.gravity.source == "depth" and np.array_equal(weak.gravity.down, depth.down) and weak.sure


def test_a_depth_map_keeps_its_own_estimate_unless_it_is_unsure(lines):
    depth = _depth(_tilted(20.0), DEPTH_SURE + 0.01)
    line = _lines(lines, _tilted(0.0), 0.9)
    kept = combine_down(depth, line, lines_first=False).gravity
    # the depth's estimate as it was: the same down and frame (the fit does not change), its source named
    assert kept.source == "depth" and kept.down is depth.down and kept.frame is depth.frame
    assert kept.confidence == depth.confidence and kept.lines_deg == pytest.approx(20.0)
    agreeing = combine_down(depth, _lines(lines, _tilted(19.0), 0.9), lines_first=False).gravity
    assert agreeing.source == "lines and depth" and agreeing.down is depth.down
    # unsure depth (low confidence): the sure lines take over
    unsure = combine_down(_depth(_tilted(20.0), DEPTH_SURE - 0.01), line, lines_first=False)
    assert unsure.gravity.source == "photo lines" and np.array_equal(unsure.gravity.down, line.down)
    # no depth estimate: the lines alone; no lines: the depth alone, no note (as without a photo)
    alone = combine_down(None, line, lines_first=False)
    assert alone.gravity.source == "photo lines" and alone.sure and alone.gravity.lines_deg is None
    assert combine_down(depth, None, lines_first=False).gravity.source == "depth"


def test_neither_sure_gives_one_note_and_the_relatively_more_confident_one(lines):
    depth = _depth(_tilted(40.0), 0.06)  # 0.4 of its bar
    line = _lines(lines, _tilted(0.0), 0.3)  # 0.75 of its bar
    for first in (True, False):
        choice = combine_down(depth, line, lines_first=first)
        assert not choice.sure and choice.gravity.source == "photo lines"
        assert choice.note.startswith("the down direction is uncertain") and "\n" not in choice.note
        assert "0.30" in choice.note and "0.06" in choice.note and "40 degrees apart" in choice.note
    only = combine_down(_depth(_tilted(5.0), 0.06), None, lines_first=True)
    assert only.gravity.source == "depth" and "no vanishing points" in only.note
    # lines that fix nothing (confidence 0) are no witness; nothing at all: no gravity
    assert combine_down(None, _lines(lines, _tilted(0.0), 0.0), lines_first=True).gravity is None
    assert combine_down(None, None, lines_first=False) == combine_down(None, None, lines_first=True)


def test_a_confidence_exactly_at_its_bar_is_sure(lines):
    depth = _depth(_tilted(30.0), 0.5)
    at_bar = _lines(lines, _tilted(0.0), LINES_SURE)
    choice = combine_down(depth, at_bar, lines_first=True)  # the first witness, just sure: it is used
    assert choice.gravity.source == "photo lines" and choice.sure and choice.note == ""
    alone = combine_down(None, at_bar, lines_first=False)  # no other witness, no agreement: still sure
    assert alone.sure and alone.note == "" and alone.gravity.source == "photo lines"
    depth_at_bar = combine_down(_depth(_tilted(30.0), DEPTH_SURE), None, lines_first=False)
    assert depth_at_bar.sure and depth_at_bar.gravity.source == "depth"


def test_a_sure_second_witness_beats_a_more_confident_unsure_first(lines):
    # lines at 0.9 of their bar, depth at 1.2 of its bar: the sure one, though the lines come first
    choice = combine_down(_depth(_tilted(30.0), 1.2 * DEPTH_SURE), _lines(lines, _tilted(0.0), 0.36), True)
    assert choice.gravity.source == "depth" and choice.sure
    # depth at 0.6 of its bar is not sure: the relatively more confident lines, with a note
    unsure = combine_down(_depth(_tilted(30.0), 0.6 * DEPTH_SURE), _lines(lines, _tilted(0.0), 0.36), True)
    assert unsure.gravity.source == "photo lines" and not unsure.sure
    assert "using the lines estimate" in unsure.note
    # and the depth's part of the note carries the angle between them
    assert f"sure from {DEPTH_SURE:g}), 30 degrees apart" in unsure.note
    deeper = combine_down(_depth(_tilted(30.0), 0.9 * DEPTH_SURE), _lines(lines, _tilted(0.0), 0.1), True)
    assert deeper.gravity.source == "depth" and "using the depth estimate" in deeper.note


def test_nothing_found_is_not_sure_and_the_choice_is_frozen():
    choice = combine_down(None, None, lines_first=True)
    assert choice.gravity is None and choice.sure is False and choice.note == ""
    with pytest.raises(dataclasses.FrozenInstanceError):
        choice.sure = True


def test_angle_deg_of_unnormalised_directions():
    assert angle_deg(np.array([0.0, 2.0, 0.0]), np.array([0.0, 0.0, 3.0])) == pytest.approx(90.0)
    assert angle_deg(np.array([2.0, 0.0, 0.0]), np.array([3.0, 3.0, 0.0])) == pytest.approx(45.0)
    assert angle_deg(np.array([0.0, 5.0, 0.0]), np.array([0.0, 0.5, 0.0])) == pytest.approx(0.0, abs=1e-6)
    assert angle_deg(np.array([0.0, 5.0, 0.0]), np.array([0.0, -0.5, 0.0])) == pytest.approx(180.0)

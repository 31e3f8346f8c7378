"""AbsRel, RMSE and delta < 1.25 on hand-computed arrays."""

from __future__ import annotations

import math

import numpy as np
import pytest

from cuboidcli.depth.metrics import abs_rel, delta_accuracy, depth_errors, mean_errors, rmse

# Valid pixels (gt > 0): (pred, gt) = (1, 1), (2, 4), (3, 2); the fourth pixel is a hole.
PRED = np.array([[1.0, 2.0], [3.0, 0.5]])
GT = np.array([[1.0, 4.0], [2.0, 0.0]])


def test_hand_computed_values():
    assert abs_rel(PRED, GT) == pytest.approx((0.0 + 2.0 / 4.0 + 1.0 / 2.0) / 3.0)
    assert rmse(PRED, GT) == pytest.approx(math.sqrt((0.0 + 4.0 + 1.0) / 3.0))
    # ratios max(d/d*, d*/d): 1, 2, 1.5 -> one of three below 1.25
    assert delta_accuracy(PRED, GT) == pytest.approx(1.0 / 3.0)
    assert delta_accuracy(PRED, GT, threshold=1.25**2) == pytest.approx(2.0 / 3.0)


def test_depth_errors_and_valid_mask():
    errors = depth_errors(PRED, GT, valid=np.array([[True, False], [True, True]]))
    assert errors["valid_px"] == 2  # the hole stays excluded
    assert errors["abs_rel"] == pytest.approx(0.25)
    assert errors["rmse_m"] == pytest.approx(math.sqrt(0.5))
    assert errors["delta1"] == pytest.approx(0.5)


def test_nan_ground_truth_is_a_hole_and_zero_prediction_a_miss():
    gt = np.array([2.0, np.nan, 1.0])
    pred = np.array([2.0, 5.0, 0.0])
    assert delta_accuracy(pred, gt) == pytest.approx(0.5)
    assert abs_rel(pred, gt) == pytest.approx(0.5)


def test_perfect_prediction():
    gt = np.linspace(0.5, 8.0, 30).reshape(5, 6)
    assert depth_errors(gt, gt) == {"abs_rel": 0.0, "rmse_m": 0.0, "delta1": 1.0, "valid_px": 30}


def test_mean_over_frames():
    frames = [{"abs_rel": 0.1, "rmse_m": 1.0, "delta1": 0.5}, {"abs_rel": 0.3, "rmse_m": 2.0, "delta1": 1.0}]
    assert mean_errors(frames) == pytest.approx({"abs_rel": 0.2, "rmse_m": 1.5, "delta1": 0.75, "frames": 2})


def test_errors():
    with pytest.raises(ValueError, match="shape"):
        abs_rel(np.ones((2, 2)), np.ones((2, 3)))
    with pytest.raises(ValueError, match="no valid"):
        rmse(np.ones(3), np.zeros(3))
    with pytest.raises(ValueError, match="NaN"):
        abs_rel(np.array([np.nan, 1.0]), np.ones(2))
    with pytest.raises(ValueError, match="no frames"):
        mean_errors([])

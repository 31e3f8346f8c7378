"""Neighbourhood graphs at their edges: a box that is not a cube, the default reach, one pair, label 0, and a
ceiling met exactly."""

from __future__ import annotations

import itertools

import numpy as np

from cuboidcli.geometry.graph import components, grow_labels, neighbour_pairs


def brute(pts: np.ndarray, cell: float, reach: int) -> set:
    keys = np.floor((pts - pts.min(0)) / cell).astype(int)
    return {
        (i, j)
        for i, j in itertools.combinations(range(len(pts)), 2)
        if np.abs(keys[i] - keys[j]).max() <= reach
    }


def test_pairs_in_a_box_of_three_different_sides_and_the_default_reach():
    rng = np.random.default_rng(1)
    pts = rng.uniform(0, 1, (250, 3)) * [0.5, 0.3, 0.8]  # 10 x 6 x 16 cells of 5 cm
    got = neighbour_pairs(pts, 0.05)
    assert {tuple(p) for p in got} == brute(pts, 0.05, 1) and len(got) > 100
    assert {tuple(p) for p in neighbour_pairs(pts, 0.05, 2)} == brute(pts, 0.05, 2)


def test_one_pair():
    pairs = neighbour_pairs(np.array([[0.0, 0.0, 0.0], [0.06, 0.0, 0.0]]), 0.05)
    assert pairs.tolist() == [[0, 1]]
    assert components(3, pairs).tolist() == [0, 0, 2]
    assert grow_labels(np.array([-1, 3]), pairs, steps=1).tolist() == [3, 3]


def test_label_zero_spreads_and_stays():
    path = np.stack([np.arange(4), np.arange(1, 5)], 1)  # 0 - 1 - 2 - 3 - 4
    assert grow_labels(np.array([0, -1, -1, -1, 1]), path, steps=5).tolist() == [0, 0, 0, 1, 1]
    assert grow_labels(np.array([0, 1]), np.array([[0, 1]]), steps=3).tolist() == [0, 1]  # labelled stays


def test_a_ceiling_is_reached_but_not_passed():
    path = np.stack([np.arange(3), np.arange(1, 4)], 1)
    height = np.array([0.0, 1.0, 1.5, 1.0])
    out = grow_labels(np.array([0, -1, -1, -1]), path, steps=5, height=height, ceiling=np.array([1.0]))
    assert out.tolist() == [0, 0, -1, -1]  # node 1 exactly at the ceiling is taken, node 2 above it is not

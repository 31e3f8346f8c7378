"""Neighbourhood graphs of voxelised points (cuboidcli.geometry.graph) against brute force."""

from __future__ import annotations

import itertools

import numpy as np
import pytest

from cuboidcli.geometry.graph import components, grow_labels, neighbour_pairs, touching_pairs


@pytest.mark.parametrize("reach", [1, 2])
def test_neighbour_pairs_equal_brute_force(reach):
    rng = np.random.default_rng(0)
    pts = rng.uniform(0, 0.5, (300, 3))
    pts[:20] = pts[20:40] + 0.001  # some points share a cell
    cell = 0.05
    got = {tuple(p) for p in neighbour_pairs(pts, cell, reach)}
    keys = np.floor((pts - pts.min(0)) / cell).astype(int)
    want = {
        (i, j)
        for i, j in itertools.combinations(range(len(pts)), 2)
        if np.abs(keys[i] - keys[j]).max() <= reach
    }
    assert got == want and len(want) > 300


@pytest.mark.parametrize("radius", [0.05, 0.0875, 0.1375])
def test_touching_pairs_equal_brute_force_wherever_the_points_lie(radius):
    """Pairs at most ``radius`` apart along every axis, whatever grid the search uses: shifting all points
    by part of a radius gives the same pairs (a grid of cells would not)."""
    rng = np.random.default_rng(1)
    pts = rng.uniform(0, 0.5, (300, 3))
    pts[:20] = pts[20:40] + 0.001
    pts[40] = pts[41] + [radius, 0.0, 0.0]  # exactly at the bound: touching
    pts[42] = pts[43] + [0.0, radius * 1.001, 0.0]  # just beyond it
    gap = np.abs(pts[:, None] - pts[None]).max(axis=2)
    want = {(i, j) for i, j in itertools.combinations(range(len(pts)), 2) if gap[i, j] <= radius}
    assert {tuple(p) for p in touching_pairs(pts, radius)} == want
    assert (40, 41) in want and (42, 43) not in want
    for shift in (0.3, 0.55):  # a point beyond the lowest corner moves where the search's cells start
        extra = np.concatenate([pts, [pts.min(0) - shift * radius]])
        got = {tuple(p) for p in touching_pairs(extra, radius) if p[1] < len(pts)}
        assert got == want
    assert touching_pairs(np.zeros((0, 3)), 0.1).shape == (0, 2)
    # two points in neighbouring cells but farther apart than the radius: no pair
    assert touching_pairs(np.array([[0.0, 0.0, 0.0], [0.15, 0.0, 0.0]]), 0.1).shape == (0, 2)


def test_components_and_empty_graphs():
    pairs = np.array([[0, 1], [1, 2], [4, 3], [6, 5], [5, 4]])
    assert components(8, pairs).tolist() == [0, 0, 0, 3, 3, 3, 3, 7]
    assert components(3, np.zeros((0, 2), dtype=np.int64)).tolist() == [0, 1, 2]
    assert neighbour_pairs(np.zeros((0, 3)), 0.1).shape == (0, 2)
    chain = np.stack([np.arange(999), np.arange(1, 1000)], 1)[::-1]  # a long chain, given backwards
    assert (components(1000, chain) == 0).all()


def test_grow_labels_takes_the_nearest_seed_in_hops():
    path = np.stack([np.arange(9), np.arange(1, 10)], 1)  # 0 - 1 - ... - 9
    seeds = np.full(10, -1)
    seeds[0], seeds[7] = 5, 2
    out = grow_labels(seeds, path, steps=20)
    assert out.tolist() == [5, 5, 5, 5, 2, 2, 2, 2, 2, 2]  # node 3 is 3 hops from 0 and 4 from 7
    tie = grow_labels(np.array([4, -1, 1]), np.array([[0, 1], [1, 2]]), steps=5)
    assert tie.tolist() == [4, 1, 1]  # reached by both in the same round: the lower label
    short = grow_labels(seeds, path, steps=1)
    assert short.tolist() == [5, 5, -1, -1, -1, -1, 2, 2, 2, -1]

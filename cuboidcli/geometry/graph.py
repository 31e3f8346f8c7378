"""Neighbourhood graphs of voxelised points: which points touch, connected parts, and growing labels.

A room's fitting points are voxel means, one per occupied voxel; two points are neighbours when their
voxels lie within ``reach`` cells of each other along every axis (26 neighbours at reach 1). Everything
here is plain numpy on edge lists, so it runs on rooms of tens of thousands of points in well under a
second.
"""

from __future__ import annotations

import numpy as np


def neighbour_pairs(points: np.ndarray, cell_m: float, reach: int = 1) -> np.ndarray:
    """(E, 2) int64 index pairs (i, j), i < j, of the points (N, 3) whose cells of side ``cell_m`` lie within
    ``reach`` cells of each other along every axis; each pair once. Points that share a cell are pairs
    too."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) == 0:
        return np.zeros((0, 2), dtype=np.int64)
    keys = np.floor((p - p.min(0)) / cell_m).astype(np.int64) + reach
    dims = keys.max(0) + reach + 1
    code = (keys[:, 0] * dims[1] + keys[:, 1]) * dims[2] + keys[:, 2]
    order = np.argsort(code, kind="stable")
    sorted_code = code[order]
    steps = range(-reach, reach + 1)
    out = []
    for a in steps:
        for b in steps:
            for c in steps:
                if (a, b, c) < (0, 0, 0):
                    continue  # the other half of each pair is found from the other point
                shifted = code + (a * dims[1] + b) * dims[2] + c
                lo = np.searchsorted(sorted_code, shifted, side="left")
                hi = np.searchsorted(sorted_code, shifted, side="right")
                count = hi - lo
                i = np.repeat(np.arange(len(p)), count)
                j = order[np.repeat(lo, count) + _ranks(count)]
                keep = i < j if (a, b, c) == (0, 0, 0) else np.ones(len(i), dtype=bool)
                out.append(np.stack([i[keep], j[keep]], 1))
    pairs = np.concatenate(out).astype(np.int64)
    return np.sort(pairs, axis=1)


def touching_pairs(points: np.ndarray, radius_m: float) -> np.ndarray:
    """(E, 2) int64 index pairs (i, j), i < j, of the points (N, 3) that lie at most ``radius_m`` apart along
    every axis; each pair once. Unlike :func:`neighbour_pairs` this does not depend on where a grid of cells
    starts: moving one point changes only its own pairs."""
    p = np.asarray(points, dtype=np.float64)
    pairs = neighbour_pairs(p, radius_m, 1)  # every pair that close lies in cells at most one apart
    if len(pairs) == 0:
        return pairs
    gap = np.abs(p[pairs[:, 0]] - p[pairs[:, 1]]).max(axis=1)
    return pairs[gap <= radius_m]


def _ranks(count: np.ndarray) -> np.ndarray:
    """0..count[k]-1 for every k, concatenated."""
    total = int(count.sum())
    if total == 0:
        return np.zeros(0, dtype=np.int64)
    starts = np.repeat(np.cumsum(count) - count, count)
    return np.arange(total) - starts


def components(n: int, pairs: np.ndarray) -> np.ndarray:
    """(n,) the connected component of each of n nodes joined by ``pairs`` (E, 2): the smallest node index
    of its component."""
    label = np.arange(n)
    if len(pairs) == 0:
        return label
    i, j = pairs[:, 0], pairs[:, 1]
    while True:
        low = np.minimum(label[i], label[j])
        new = label.copy()
        np.minimum.at(new, i, low)
        np.minimum.at(new, j, low)
        new = new[new]  # pointer jumping: long chains settle in a few rounds
        if np.array_equal(new, label):
            return label
        label = new


def grow_labels(
    labels: np.ndarray,
    pairs: np.ndarray,
    steps: int,
    height: np.ndarray | None = None,
    ceiling: np.ndarray | None = None,
) -> np.ndarray:
    """Labels (n,) (-1 = none) spread over the graph ``pairs`` for at most ``steps`` rounds, all labels at
    the same pace: each unlabelled node takes the label of a labelled neighbour (of the lowest such label
    when several reach it in the same round), so it ends with the label nearest to it in hops.

    With ``height`` (n,) and ``ceiling`` (one value per label), label k takes no node higher than
    ``ceiling[k]``."""
    out = np.asarray(labels).copy()
    if len(pairs) == 0:
        return out
    both = np.concatenate([pairs, pairs[:, ::-1]])
    src, dst = both[:, 0], both[:, 1]
    big = np.iinfo(out.dtype).max
    for _ in range(steps):
        reach = (out[src] >= 0) & (out[dst] < 0)
        if ceiling is not None:
            reach[reach] &= height[dst[reach]] <= ceiling[out[src[reach]]]
        if not reach.any():
            break
        cand = np.full(len(out), big, dtype=out.dtype)
        np.minimum.at(cand, dst[reach], out[src[reach]])
        newly = cand < big
        out[newly] = cand[newly]
    return out

"""The same seed gives the same cuboids: across runs and across torch / numba thread counts."""

from __future__ import annotations

import numba
import numpy as np
import torch

from cuboidcli.fitting.config import FitConfig
from tests.conftest import fit_named


def _fit(depth, camera, threads: int):
    torch_before, numba_before = torch.get_num_threads(), numba.get_num_threads()
    torch.set_num_threads(threads)
    numba.set_num_threads(min(threads, numba.config.NUMBA_NUM_THREADS))
    try:
        return fit_named(depth, camera, FitConfig(seed=11, hypotheses=384, max_cuboids=4))[0]
    finally:
        torch.set_num_threads(torch_before)
        numba.set_num_threads(numba_before)


def test_same_seed_same_cuboids_for_any_thread_count(room_depth, nyu_camera):
    depth, _ = room_depth
    one = _fit(depth, nyu_camera, 1)
    assert len(one) >= 2
    for threads in (2, 1):
        other = _fit(depth, nyu_camera, threads)
        assert len(other) == len(one)
        for a, b in zip(one, other, strict=True):
            np.testing.assert_array_equal(a.center, b.center)
            np.testing.assert_array_equal(a.half_size, b.half_size)
            np.testing.assert_array_equal(a.rotation, b.rotation)
            assert a.inlier_gain == b.inlier_gain

"""Cost of the evaluation metrics on one full-resolution frame (480x640 = 307,200 points, 8 cuboids).

    .venv/bin/python benchmarks/bench_metrics.py [--repeat 5] [--cuboids 8]

Prints per-stage timings (best and median of the repeats, after one warm-up that compiles or loads the
numba kernels) and the peak resident memory. The budget is 0.3 s per frame for all metrics together.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time

import numpy as np
import torch

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.auc import AucStats
from cuboidcli.evaluation.coverage import coverage_mask
from cuboidcli.evaluation.metrics import frame_metrics
from cuboidcli.evaluation.oa import oa_distances
from cuboidcli.evaluation.raycast import render_depth
from cuboidcli.geometry.kernels import oa_sq_distance


def scene(n_cuboids: int, seed: int = 0) -> tuple[Camera, np.ndarray, list[Cuboid]]:
    """A rendered room with furniture-sized boxes, and a cuboid set that only roughly matches it."""
    rng = np.random.default_rng(seed)
    cam = Camera.preset("nyu")
    room = Cuboid([0.0, -0.2, 3.0], [2.5, 1.5, 3.5], np.eye(3))
    boxes = []
    for _ in range(n_cuboids - 1):
        a = rng.uniform(-0.5, 0.5)
        rot = np.array([[np.cos(a), 0.0, np.sin(a)], [0.0, 1.0, 0.0], [-np.sin(a), 0.0, np.cos(a)]])
        boxes.append(Cuboid(rng.uniform([-1.5, 0.3, 2.0], [1.5, 1.0, 5.0]), rng.uniform(0.2, 0.6, 3), rot))
    depth = render_depth(cam, [room, *boxes])
    fitted = [
        Cuboid(c.center + rng.normal(0, 0.03, 3), c.half_size * rng.uniform(0.9, 1.1, 3), c.rotation)
        for c in [room, *boxes]
    ]
    return cam, depth, fitted


def timed(fn, repeat: int) -> tuple[float, float]:
    fn()  # warm-up: numba compilation / cache load
    times = []
    for _ in range(repeat):
        t = time.perf_counter()
        fn()
        times.append(time.perf_counter() - t)
    return min(times), statistics.median(times)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=5)
    parser.add_argument("--cuboids", type=int, default=8)
    args = parser.parse_args()

    cam, depth, cuboids = scene(args.cuboids)
    valid = valid_depth(depth)
    points = cam.backproject(depth)[valid]
    dist = oa_distances(points, cuboids)
    print(
        f"frame {cam.width}x{cam.height}, {points.shape[0]} valid points, {len(cuboids)} cuboids, "
        f"torch threads {torch.get_num_threads()}"
    )
    stages = {
        "backproject": lambda: cam.backproject(depth)[valid],
        "OA-L2 distances (numba)": lambda: oa_distances(points, cuboids),
        "coverage (clip + hull + fill)": lambda: coverage_mask(cam, cuboids),
        "AUC statistics @20,5 cm": lambda: [AucStats.of(dist, x) for x in (0.20, 0.05)],
        "all metrics (frame_metrics)": lambda: frame_metrics("bench", depth, cam, cuboids),
    }
    for name, fn in stages.items():
        best, med = timed(fn, args.repeat)
        print(f"  {name:32s} best {best * 1000:8.1f} ms   median {med * 1000:8.1f} ms")

    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f"peak RSS {peak_mb:.0f} MB after the metrics (process total: Python, torch, numba, the frame)")
    # the torch reference kernel materialises (M, N, 6) side tensors; time it on 1/8 of the points
    sub = torch.from_numpy(points[::8].copy())
    c, a, r = (
        torch.tensor(np.stack([getattr(b, key) for b in cuboids]))
        for key in ("center", "half_size", "rotation")
    )
    best, med = timed(lambda: oa_sq_distance(sub, c, a, r), max(1, args.repeat // 2))
    print(
        f"  {'torch reference, 1/8 of points':32s} best {best * 1000:8.1f} ms   median {med * 1000:8.1f} ms"
        f"   (x8 = {8 * best:.2f} s per frame)"
    )
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024.0
    print(f"peak RSS {peak_mb:.0f} MB after the torch reference run")


if __name__ == "__main__":
    main()

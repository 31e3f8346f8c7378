"""Speed of the solver stage alone: the numerical solver (PCA + Adam, fused numba loop) against the neural
solver (one forward pass of the regression network) on the same minimal sets.

The sets are C = 6 fitting points (float64, metres) drawn uniformly with a seeded generator from the
fitting grid (every 8th pixel) of a synthetic NYU-like room, i.e. what the estimator hands the solver in
one step of 4096 hypotheses. Per solver and thread count: one warm-up call (kernel compile / cache load,
thread pool start), then the median of --repeats timed calls. The thread count is set for torch, numba and
the neural solver's own thread pool (``NeuralSolver.threads``).

    python benchmarks/bench_solver.py [--sets 4096] [--repeats 10] [--threads 1,2] [--weights PATH]
        [--seed 0]

--weights: the neural solver's weights, a .pt file or a folder holding solver_v1.pt (default: the shipped
models/solver_v1.pt). Prints ms per call, sets per second, the speed-up of the neural solver over the
numerical one per thread count, the network's parameter count and the peak RSS of the process.
"""

from __future__ import annotations

import argparse
import resource
import statistics
import time
from pathlib import Path


def minimal_sets(n_sets: int, set_size: int, seed: int):
    """(n_sets, set_size, 3) float64 points of a synthetic room's fitting grid, and the grid's point count."""
    import torch

    from cuboidcli.camera import Camera
    from cuboidcli.fitting.prepare import prepare_points
    from cuboidcli.synth.scene import generate_scene

    cam = Camera.preset("nyu")
    scene = generate_scene((2024, 0), cam)
    pts = prepare_points(scene.depth_m, cam, 8).as_tensors().points.double()
    gen = torch.Generator().manual_seed(seed)
    idx = torch.randint(0, pts.shape[0], (n_sets, set_size), generator=gen)
    return pts[idx].contiguous(), int(pts.shape[0])


def time_calls(fn, x, repeats: int) -> tuple[float, float]:
    """(warm-up seconds, median seconds of ``repeats`` calls)."""
    t = time.perf_counter()
    fn(x)
    warm = time.perf_counter() - t
    times = []
    for _ in range(repeats):
        t = time.perf_counter()
        fn(x)
        times.append(time.perf_counter() - t)
    return warm, statistics.median(times)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--sets", type=int, default=4096, help="minimal sets per call")
    ap.add_argument("--repeats", type=int, default=10, help="timed calls per solver and thread count")
    ap.add_argument("--threads", default="1,2", help="comma-separated thread counts")
    ap.add_argument("--weights", type=Path, default=None, help="neural solver weights (.pt or folder)")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    try:
        thread_counts = [int(s) for s in args.threads.split(",") if s.strip()]
    except ValueError:
        ap.error(f"--threads {args.threads!r}: give comma-separated integers, e.g. 1,2")
    if not thread_counts or min(thread_counts) < 1:
        ap.error(f"--threads {args.threads!r}: give positive thread counts")
    if args.sets < 1 or args.repeats < 1:
        ap.error("--sets and --repeats must be positive")

    import numba
    import torch

    from cuboidcli.factories import make_solver
    from cuboidcli.fitting.config import FitConfig
    from cuboidcli.fitting.pipeline import ensure_compiled
    from cuboidcli.nets.checkpoint import parameter_count

    if max(thread_counts) > numba.config.NUMBA_NUM_THREADS:
        ap.error(
            f"--threads {args.threads}: numba allows at most {numba.config.NUMBA_NUM_THREADS} threads "
            "in this process (set NUMBA_NUM_THREADS to raise it)"
        )
    config = FitConfig()
    numerical = make_solver(FitConfig(solver="numerical"))
    t = time.perf_counter()
    ensure_compiled(numerical)
    compile_s = time.perf_counter() - t
    sets, n_points = minimal_sets(args.sets, config.min_set, args.seed)
    neural = make_solver(FitConfig(solver="neural"), args.weights)
    weights = args.weights if args.weights is not None else "shipped (models/solver_v1.pt)"
    print(
        f"sets: {args.sets} x C={config.min_set} points ({sets.dtype}) from {n_points} fitting points of "
        f"synthetic room (2024, 0); repeats {args.repeats}; kernel compile/cache load {compile_s:.2f} s"
    )
    print(
        f"numerical: Adam lr {numerical.lr:g}, {numerical.iters} iterations; neural: weights {weights}, "
        f"{parameter_count(neural.net):,} parameters, config {neural.net.config.to_dict()}"
    )
    print()
    header = f"{'solver':10s} {'threads':>7s} {'warm-up ms':>10s} {'ms/call':>9s} {'sets/s':>10s}"
    print(header)
    print("-" * len(header))
    median: dict[tuple[str, int], float] = {}
    for n in thread_counts:
        torch.set_num_threads(n)
        numba.set_num_threads(n)
        neural.threads = n
        for name, solver in (("numerical", numerical), ("neural", neural)):
            warm, med = time_calls(solver, sets, args.repeats)
            median[name, n] = med
            print(f"{name:10s} {n:7d} {1e3 * warm:10.1f} {1e3 * med:9.1f} {args.sets / med:10.0f}")
    print()
    for n in thread_counts:
        print(
            f"speed-up neural vs numerical, {n} thread(s): "
            f"{median['numerical', n] / median['neural', n]:.2f}x"
        )
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS: {peak_mb:.0f} MB")


if __name__ == "__main__":
    main()

"""Fitting speed and memory at the paper's settings: 480x640 depth, every 8th pixel (<= 4800 fitting
points), at most 8 cuboids, numerical solver (or the neural one: --solver neural), 3072 hypotheses per step
(the default; the paper's 4096 with --hypotheses 4096).

Prints per-frame and mean per-stage timings (s) and the peak RSS of the process. Frames: synthetic NYU-like
rooms from the scene generator (always) and the real frames in ../shared/data (when present). The solver and
the sampler are built once, before the first frame (weights loading is not timed). 'total' is input loaded
-> cuboids selected (FitInfo.timing_s); 'assign' (per-pixel labels, after selection) is not part of it.

    python benchmarks/bench_fit.py [--frames 5] [--fast] [--no-refine] [--sampler sequential]
        [--solver numerical|neural] [--weights PATH] [--hypotheses 4096] [--seed 0]
        [--local-fraction 0.75] [--max-batches 4] [--align free|gravity|manhattan]
        [--device cpu|cuda|auto] [--log benchmarks/logs/fit_cuda.txt] [--open3d [--open3d-voxel 0]]

The first lines say where it ran: the date, the commit (with "+changes" for a working tree that differs
from it), the device (the GPU's name on cuda), torch and the CPU. ``--log`` writes everything printed to
that file as well, for the figures quoted in the documentation.

--open3d also times, on each frame, the pipeline a user would assemble from Open3D
(:func:`cuboidcli.evaluation.baseline.planes_and_clusters`: RANSAC planes, then DBSCAN boxes, on all the
frame's valid pixels back-projected, up = the camera's -y, down-sampled to --open3d-voxel metres first:
0.03 by default, 0 for every pixel) and prints the ratio of the median totals.

--weights: a folder (solver_v1.pt / sampler_v2.pt inside) or a .pt file; it goes to the neural solver and
the learned sampler (the other solvers and samplers have no weights). None = the shipped weights.
"""

from __future__ import annotations

import argparse
import resource
import subprocess
import sys
import time
from dataclasses import replace
from datetime import datetime, timezone
from pathlib import Path

import numpy as np


def frames(n_synth: int):
    from cuboidcli.camera import Camera
    from cuboidcli.synth.scene import generate_scene

    cam = Camera.preset("nyu")
    for i in range(n_synth):
        s = generate_scene((2024, i), cam)
        yield f"synth_{i:02d}", s.depth_m, cam
    shared = Path(__file__).resolve().parents[2] / "shared" / "data"
    if shared.is_dir():
        from cuboidcli.io.dataset import list_frames

        for sub in ("nyu", "tum"):
            if (shared / sub).is_dir():
                for f in list_frames(shared / sub):
                    yield f"{sub}/{f.name}", f.depth_m(), f.camera


def time_open3d(depth: np.ndarray, cam, seed: int, voxel_m: float) -> float:
    """Seconds of the Open3D planes + DBSCAN boxes pipeline on the frame's valid pixels."""
    from cuboidcli.evaluation.baseline import planes_and_clusters

    points = cam.backproject_grid(depth, 1)[depth > 0]
    t = time.perf_counter()
    planes_and_clusters(points, up=np.array([0.0, -1.0, 0.0]), voxel_m=voxel_m, seed=seed)
    return time.perf_counter() - t


class Tee:
    """Writes to the console and to a log file."""

    def __init__(self, *streams) -> None:
        self.streams = streams

    def write(self, text: str) -> int:
        for stream in self.streams:
            stream.write(text)
            stream.flush()
        return len(text)

    def flush(self) -> None:
        for stream in self.streams:
            stream.flush()


def where_it_ran(device: str, machine: dict) -> list[str]:
    """The date, the commit, the device and the software of a run, as lines."""
    root = Path(__file__).resolve().parents[1]

    def git(*args: str) -> str:
        try:
            return subprocess.run(["git", *args], cwd=root, capture_output=True, text=True).stdout.strip()
        except OSError:
            return ""

    commit = git("rev-parse", "--short", "HEAD") or "unknown"
    if git("status", "--porcelain", "--untracked-files=no"):
        commit += "+changes"
    gpu = f" ({machine['cuda']})" if device == "cuda" else ""
    return [
        f"date {datetime.now(timezone.utc):%Y-%m-%d %H:%M} UTC, commit {commit}",
        f"device {device}{gpu}; torch {machine['torch']}; CPU {machine['processor']}, "
        f"{machine['cpu_count']} cores",
    ]


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=5, help="synthetic frames")
    ap.add_argument("--fast", action="store_true", help="approximate scoring (prescore on 600 points)")
    ap.add_argument("--no-refine", action="store_true")
    ap.add_argument("--sampler", default="sequential", help="uniform | sequential | local | learned")
    ap.add_argument("--solver", default="numerical", choices=("numerical", "neural"))
    ap.add_argument(
        "--weights", type=Path, default=None, help="weights folder or .pt (neural solver / learned sampler)"
    )
    ap.add_argument("--hypotheses", type=int, default=3072)
    ap.add_argument("--seed", type=int, default=0)
    ap.add_argument("--local-fraction", type=float, default=None, help="share of localised minimal sets")
    ap.add_argument("--max-batches", type=int, default=None, help="adaptive termination: batches per step")
    ap.add_argument("--align", default=None, help="free | gravity | manhattan (default: the library's)")
    ap.add_argument("--device", default="cpu", help="cpu | cuda | auto (cuda when there is one)")
    ap.add_argument("--log", type=Path, default=None, help="also write the output to this file")
    ap.add_argument("--open3d", action="store_true", help="also time the Open3D planes + DBSCAN pipeline")
    ap.add_argument("--open3d-voxel", type=float, default=0.03, help="its voxel size, m (0: every pixel)")
    args = ap.parse_args()
    if args.log is not None:
        args.log.parent.mkdir(parents=True, exist_ok=True)
        sys.stdout = Tee(sys.stdout, args.log.open("w", encoding="utf-8"))

    import torch

    from cuboidcli.evaluation.provenance import machine_info
    from cuboidcli.factories import make_sampler, make_solver
    from cuboidcli.fitting.config import FitConfig, resolve_device
    from cuboidcli.fitting.pipeline import ensure_compiled, fit_depth

    try:
        device = resolve_device(args.device, "--device")
    except ValueError as e:
        ap.error(str(e))
    for line in where_it_ran(device, machine_info()):
        print(line)
    cfg = FitConfig(
        device=device,
        hypotheses=args.hypotheses,
        sampler=args.sampler,
        solver=args.solver,
        seed=args.seed,
        refine=not args.no_refine,
        prescore_points=600 if args.fast else 0,
    )
    overrides = {"local_fraction": args.local_fraction, "max_batches": args.max_batches, "align": args.align}
    cfg = replace(cfg, **{k: v for k, v in overrides.items() if v is not None})
    if (
        args.weights is not None
        and args.weights.suffix == ".pt"
        and (cfg.solver, cfg.sampler)
        == (
            "neural",
            "learned",
        )
    ):
        ap.error("--weights: with --solver neural and --sampler learned give a folder, not one .pt file")
    t = time.perf_counter()
    solver = make_solver(cfg, args.weights)
    sampler = make_sampler(cfg.sampler, args.weights)
    print(
        f"solver {cfg.solver}, sampler {cfg.sampler}, weights {args.weights or 'shipped'}: "
        f"built in {time.perf_counter() - t:.2f} s"
    )
    t = time.perf_counter()
    ensure_compiled(solver, sampler)
    print(
        f"start-up (kernel compile/cache load): {time.perf_counter() - t:.2f} s; torch threads "
        f"{torch.get_num_threads()}"
    )
    stages = ("prepare", "gravity", "sample", "solve", "score", "refine", "align", "update", "total")
    stages += ("assign",)
    header = f"{'frame':28s} {'pts':>5s} {'|M|':>3s} {'steps':>5s} " + " ".join(f"{s:>7s}" for s in stages)
    print(header + ("  open3d" if args.open3d else ""))
    rows, open3d_s = [], []
    for name, depth, cam in frames(args.frames):
        cubs, info = fit_depth(depth, cam, cfg, solver=solver, sampler=sampler)
        t = info.timing_s
        rows.append([t.get(s, 0.0) for s in stages])
        extra = ""
        if args.open3d:
            open3d_s.append(time_open3d(depth, cam, args.seed, args.open3d_voxel))
            extra = f" {open3d_s[-1]:7.3f}"
        print(
            f"{name:28s} {info.n_points:5d} {len(cubs):3d} {info.iterations:5d} "
            + " ".join(f"{t.get(s, 0.0):7.3f}" for s in stages)
            + extra
        )
    mean = np.mean(rows, axis=0)
    print(f"{'mean':28s} {'':5s} {'':3s} {'':5s} " + " ".join(f"{v:7.3f}" for v in mean))
    median = np.median(rows, axis=0)
    print(f"{'median':28s} {'':5s} {'':3s} {'':5s} " + " ".join(f"{v:7.3f}" for v in median))
    if open3d_s:
        ours = float(median[stages.index("total")])
        theirs = float(np.median(open3d_s))
        print(f"median total {ours:.3f} s, Open3D planes + DBSCAN {theirs:.3f} s: ratio {ours / theirs:.2f}")
    peak_mb = resource.getrusage(resource.RUSAGE_SELF).ru_maxrss / 1024
    print(f"peak RSS: {peak_mb:.0f} MB")


if __name__ == "__main__":
    main()

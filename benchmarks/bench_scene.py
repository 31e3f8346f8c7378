"""Time and memory of fitting a whole room, per stage: a synthetic room scan fused to points, fitted as a
bare cloud of ``--points`` points (sampled from the fused scan) and as its sequence, each in a fresh process
so peak memory is the fit's own.

    python benchmarks/bench_scene.py --points 50000 500000 --runs 2
    python benchmarks/bench_scene.py --points --no-sequence --scan ../shared/data/scannet/scene0001_00.ply

Prints one line per case: input points, fitting points, cuboids, the stages of ``timing_s`` (``load`` is
reading the file, outside ``total``; ``objects`` after it), wall time of the whole command, peak resident
memory, and whether the command imported torch (a room fitted with the default parts on the CPU does not).
"""

from __future__ import annotations

import argparse
import json
import subprocess
import sys
import tempfile
import time
from pathlib import Path

import numpy as np

STAGES = ("load", "prepare", "gravity", "sample", "solve", "score", "refine", "align", "total", "objects")


def make_scan(root: Path, seed: int, views: int) -> Path:
    from cuboidcli.camera import Camera
    from cuboidcli.synth.scan import generate_room_scan, write_room_scan

    return write_room_scan(root / "scan", generate_room_scan(seed, views, Camera.preset("nyu")))


def run_case(path: Path, out: Path) -> dict:
    """``cuboids fit`` in a fresh process under /usr/bin/time -v-like accounting (resource usage of the
    child): returns timing_s, wall seconds and peak RSS (MB)."""
    code = (
        "import resource, sys, time; from cuboidcli.cli.main import run; t = time.perf_counter();\n"
        "try:\n    run()\nexcept SystemExit:\n    pass\n"
        "print('WALL', time.perf_counter() - t, 'RSS', resource.getrusage(resource.RUSAGE_SELF).ru_maxrss,\n"
        "      'TORCH', 'torch' in sys.modules)"
    )
    # sys.argv[0] stands for the program name the command line parser skips
    cmd = [sys.executable, "-c", code, "fit", str(path), "-o", str(out), "-q"]
    done = subprocess.run(cmd, capture_output=True, text=True, check=True)
    line = [w for w in done.stdout.split("\n") if w.startswith("WALL")][-1].split()
    d = json.loads(out.read_text())
    return {
        "timing": d["timing_s"],
        "wall": float(line[1]),
        "rss_mb": float(line[3]) / 1024,
        "torch": line[5] == "True",
        "n_cuboids": len(d["cuboids"]),
        "n_fit": d["fit_info"]["n_points"],
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--points", type=int, nargs="*", default=[50000, 500000])
    ap.add_argument("--scan", action="append", default=[], help="also fit this scan file (repeatable)")
    ap.add_argument("--no-sequence", action="store_true", help="skip the fused sequence's case")
    ap.add_argument("--runs", type=int, default=1)
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--views", type=int, default=12)
    args = ap.parse_args()
    from cuboidcli.io.sequence import read_sequence
    from cuboidcli.load.fuse import fuse_sequence

    with tempfile.TemporaryDirectory() as tmp:
        tmp = Path(tmp)
        cases = []
        synthetic = bool(args.points) or not args.no_sequence
        scan = make_scan(tmp, args.seed, args.views) if synthetic else None
        cloud = fuse_sequence(read_sequence(scan), voxel_m=0.005) if args.points else None
        rng = np.random.default_rng(0)
        for n in args.points:
            pick = rng.choice(len(cloud.points), n, replace=n > len(cloud.points))
            jitter = rng.normal(0, 0.002, (n, 3)) if n > len(cloud.points) else 0.0
            path = tmp / f"room_{n}.npy"
            np.save(path, (cloud.points[pick] + jitter).astype(np.float32))
            cases.append((f"bare cloud, {n} points", path))
        if not args.no_sequence:
            cases.append((f"sequence, {args.views} frames 640x480", scan))
        cases += [(Path(p).name, Path(p).resolve()) for p in args.scan]
        head = ["input", "fitting points", "cuboids", *STAGES, "wall (s)", "peak RSS (MB)", "torch"]
        print(f"| {' | '.join(head)} |")
        print("|---" * len(head) + "|")
        for name, path in cases:
            for _ in range(args.runs):
                r = run_case(path, tmp / "out.json")
                t = r["timing"]
                stages = " | ".join(f"{t.get(k, 0.0):.2f}" for k in STAGES)
                print(
                    f"| {name} | {r['n_fit']} | {r['n_cuboids']} | {stages} | {r['wall']:.1f} | "
                    f"{r['rss_mb']:.0f} | {'yes' if r['torch'] else 'no'} |",
                    flush=True,
                )


if __name__ == "__main__":
    start = time.perf_counter()
    main()
    print(f"benchmark took {time.perf_counter() - start:.0f} s")

"""The wall time of the commands a user types, each as a fresh process: the start-up (``cuboids --help``,
``--version``, ``cuboids fit --help``) and a whole fit of the sample depth map (start-up, loading, fitting,
writing). Each command runs once to warm the file cache, then ``--runs`` times; the table gives the
minimum, median and maximum wall seconds and the largest peak RSS of the runs.

    python benchmarks/bench_startup.py [--runs 5] [--cuboids PATH/TO/cuboids]

Quote medians; on a shared machine the maximum says how noisy the runs were.
"""

from __future__ import annotations

import argparse
import os
import shutil
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path

SAMPLE = Path(__file__).resolve().parents[1] / "cuboidcli" / "data" / "sample"


def commands(out: Path) -> dict[str, list[str]]:
    fit = ["fit", "--depth", str(SAMPLE / "sample_depth.png"), "-K", str(SAMPLE / "camera.json")]
    return {
        "cuboids --help": ["--help"],
        "cuboids --version": ["--version"],
        "cuboids fit --help": ["fit", "--help"],
        "cuboids fit --depth sample -K camera.json": [*fit, "-o", str(out / "sample.json")],
    }


def run_once(argv: list[str]) -> tuple[float, float]:
    """Wall seconds and peak RSS (MB) of one run; the run must succeed."""
    with tempfile.TemporaryFile() as err:
        start = time.perf_counter()
        proc = subprocess.Popen(argv, stdout=subprocess.DEVNULL, stderr=err)
        _, status, usage = os.wait4(proc.pid, 0)  # this run's own peak memory, not the largest child's
        wall = time.perf_counter() - start
        proc.returncode = os.waitstatus_to_exitcode(status)
        if proc.returncode != 0:
            err.seek(0)
            raise SystemExit(f"{' '.join(argv)} failed ({proc.returncode}):\n{err.read()[-2000:].decode()}")
    return wall, usage.ru_maxrss / 1024


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--runs", type=int, default=5, help="counted runs of each command (after one warm-up)")
    ap.add_argument("--cuboids", default=shutil.which("cuboids"), help="the console script to time")
    args = ap.parse_args()
    if args.cuboids is None or not os.path.exists(args.cuboids):
        sys.exit("no cuboids console script found: install the package or give --cuboids PATH")
    if args.runs < 1:
        sys.exit("--runs must be at least 1")
    print(f"{args.cuboids}, {args.runs} runs after one warm-up, {os.cpu_count()} CPUs")
    print("| command | min s | median s | max s | peak MB |")
    print("|---|---|---|---|---|")
    with tempfile.TemporaryDirectory() as tmp:
        for label, argv in commands(Path(tmp)).items():
            argv = [args.cuboids, *argv]
            run_once(argv)
            runs = [run_once(argv) for _ in range(args.runs)]
            walls = [w for w, _ in runs]
            peak = max(m for _, m in runs)
            cells = (f"{v:.2f}" for v in (min(walls), statistics.median(walls), max(walls)))
            print(f"| {label} | {' | '.join(cells)} | {peak:.0f} |", flush=True)


if __name__ == "__main__":
    main()

"""A large photo against a small one: wall time and peak memory of ``cuboids fit PHOTO --overlay --glb`` for
a 640x480 copy and a 12 MP (4000x3000) copy of the same photo, run side by side.

Both copies are made from the photo given (area averaging down, bicubic up; JPEG quality 90) in a temporary
folder, so the two differ only in size. The runs alternate (small, large, small, ...) so that whatever else
the machine does weighs on both alike; the table shows each run and the medians, and the large photo's
median over the small one's. Peak memory is the maximum resident set size of the command's process, as the
kernel reports it when the process ends; CPU is its user + system time, which other work on a busy machine
inflates less than the wall time (compare the wall times of runs made on a quiet machine). On a busy machine
``--single-thread`` runs torch, numba and OpenCV on one thread each: idle worker threads then spin for no
one, and the CPU time is the work done.

    python benchmarks/bench_photo.py PHOTO [--runs 3] [--large 4000x3000] [--small 640x480]
        [--single-thread] [--keep DIR] [-- extra fit options]
"""

from __future__ import annotations

import argparse
import os
import statistics
import subprocess
import sys
import tempfile
import time
from pathlib import Path


def size(text: str) -> tuple[int, int]:
    w, _, h = text.lower().partition("x")
    return int(w), int(h)


def make_copy(photo: Path, width: int, height: int, out: Path) -> Path:
    """``photo`` resized to width x height, saved as a quality-90 JPEG at ``out``."""
    import cv2

    img = cv2.imread(str(photo), cv2.IMREAD_COLOR)
    if img is None:
        raise SystemExit(f"cannot read {photo} as a colour image")
    shrink = width < img.shape[1] and height < img.shape[0]
    img = cv2.resize(img, (width, height), interpolation=cv2.INTER_AREA if shrink else cv2.INTER_CUBIC)
    if not cv2.imwrite(str(out), img, [cv2.IMWRITE_JPEG_QUALITY, 90]):
        raise SystemExit(f"cannot write {out}")
    return out


#: The thread counts --single-thread sets: torch's and numpy's BLAS (OpenMP), numba's, OpenCV's.
ONE_THREAD = {
    "OMP_NUM_THREADS": "1",
    "MKL_NUM_THREADS": "1",
    "NUMBA_NUM_THREADS": "1",
    "OPENCV_FOR_THREADS_NUM": "1",
}


def run_once(
    photo: Path, out_dir: Path, extra: list[str], single_thread: bool = False
) -> tuple[float, float, float]:
    """(wall seconds, CPU seconds, peak RSS in MB) of one ``cuboids fit`` of ``photo`` in a fresh
    process."""
    repo = Path(__file__).resolve().parents[1]
    env = {
        **os.environ,
        "PYTHONPATH": os.pathsep.join(filter(None, [str(repo), os.environ.get("PYTHONPATH")])),
    }
    if single_thread:
        env.update(ONE_THREAD)
    cmd = [sys.executable, "-m", "cuboidcli.cli.main", "fit", str(photo), "--overlay", "--glb"]
    cmd += ["-o", str(out_dir / f"{photo.stem}.json"), *extra]
    t0 = time.perf_counter()
    # run from the repository: "python -m" puts the working folder first on the path, so another
    # checkout there would be measured instead of this one
    proc = subprocess.Popen(cmd, cwd=repo, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.PIPE)
    # wait4 gives this process's own resource use (ru_maxrss in KiB on Linux), not all children's
    _, status, usage = os.wait4(proc.pid, 0)
    wall = time.perf_counter() - t0
    err = proc.stderr.read().decode(errors="replace") if proc.stderr else ""
    proc.returncode = os.waitstatus_to_exitcode(status)
    if proc.returncode != 0:
        raise SystemExit(f"{' '.join(cmd)} failed ({proc.returncode}):\n{err[-2000:]}")
    return wall, usage.ru_utime + usage.ru_stime, usage.ru_maxrss / 1024.0


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("photo", type=Path)
    ap.add_argument("--runs", type=int, default=3, help="runs of each size, alternating")
    ap.add_argument("--small", type=size, default=(640, 480), help="WxH of the small copy")
    ap.add_argument("--large", type=size, default=(4000, 3000), help="WxH of the large copy")
    ap.add_argument("--single-thread", action="store_true", help="one thread each for torch, numba, OpenCV")
    ap.add_argument("--keep", type=Path, default=None, help="write the copies and outputs here and keep them")
    ap.add_argument("extra", nargs="*", help="further options of cuboids fit (after --)")
    args = ap.parse_args()

    with tempfile.TemporaryDirectory(prefix="bench_photo_") as tmp:
        work = args.keep or Path(tmp)
        work.mkdir(parents=True, exist_ok=True)
        sizes = {"small": args.small, "large": args.large}
        photos = {k: make_copy(args.photo, w, h, work / f"{k}_{w}x{h}.jpg") for k, (w, h) in sizes.items()}
        rows: dict[str, list[tuple[float, float, float]]] = {k: [] for k in sizes}
        for i in range(args.runs):
            for k in sizes:
                out = work / f"out_{k}"
                out.mkdir(exist_ok=True)
                wall, cpu, rss = run_once(photos[k], out, args.extra, args.single_thread)
                rows[k].append((wall, cpu, rss))
                w, h = sizes[k]
                print(f"run {i + 1} {w}x{h}: {wall:6.2f} s wall {cpu:6.2f} s CPU {rss:7.0f} MB", flush=True)

    print()
    header = ["photo", "wall s (median)", "wall s (runs)", "CPU s (median)", "peak RSS MB (max)"]
    print(" | ".join(f"{x:>17s}" for x in header))
    wall_med, cpu_med = {}, {}
    for k, (w, h) in sizes.items():
        wall_med[k] = statistics.median(r[0] for r in rows[k])
        cpu_med[k] = statistics.median(r[1] for r in rows[k])
        runs = " ".join(f"{r[0]:.2f}" for r in rows[k])
        cells = [
            f"{w}x{h}",
            f"{wall_med[k]:.2f}",
            runs,
            f"{cpu_med[k]:.2f}",
            f"{max(r[2] for r in rows[k]):.0f}",
        ]
        print(" | ".join(f"{x:>17s}" for x in cells))
    print(
        f"large / small (medians): wall {wall_med['large'] / wall_med['small']:.2f}x, "
        f"CPU {cpu_med['large'] / cpu_med['small']:.2f}x"
    )


if __name__ == "__main__":
    main()

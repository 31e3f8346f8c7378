"""Throughput of folder fitting (``cuboids fit DIR``) on each engine: this process, N local worker
processes, a local Ray (or a running cluster).

Writes ``--frames`` synthetic NYU-like rooms (640x480 millimetre depth PNGs from the scene generator, seeds
(2024, i)) to a folder, then fits the folder once per engine with the default settings (or those given) and
prints, per engine: wall time, start-up (until the first frame is done: worker processes or Ray starting,
weights loading, kernel cache), frames/s over the whole run and frames/s after the first frame (the steady
state a long run approaches). Every engine writes into its own output folder; the cuboids are checked to be
identical across engines.

    python benchmarks/bench_scaleout.py [--frames 24] [--engines 1,2,ray] [--workers 2]
        [--ray-address auto] [--hypotheses 3072] [--keep DIR] [--json out.json]
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np


def write_frames(folder: Path, n: int) -> list[Path]:
    from cuboidcli.camera import Camera
    from cuboidcli.synth.scene import generate_scene

    cam = Camera.preset("nyu")
    folder.mkdir(parents=True, exist_ok=True)
    paths = []
    for i in range(n):
        depth = generate_scene((2024, i), cam).depth_m
        path = folder / f"room_{i:04d}.png"
        cv2.imwrite(str(path), np.round(np.nan_to_num(depth) * 1000).astype(np.uint16))
        paths.append(path)
    return paths


def run_engine(label: str, files: list[Path], out: Path, config, workers: int, ray: str | None) -> dict:
    from cuboidcli.job import Job, fit_task
    from cuboidcli.load import LoadOptions
    from cuboidcli.scaleout import run_tasks

    out.mkdir(parents=True, exist_ok=True)
    job = Job(config=config, options=LoadOptions(camera="nyu"), source="depth")
    tasks = [(job, str(f), str(out / f"{f.stem}_cuboids.json")) for f in files]
    stamps: list[float] = []
    t0 = time.perf_counter()
    outcomes = run_tasks(
        fit_task,
        tasks,
        [f.name for f in files],
        workers=workers,
        ray=ray,
        on_result=lambda i, o: stamps.append(time.perf_counter()),
    )
    wall = time.perf_counter() - t0
    failed = [o for o in outcomes if o.status != "done"]
    if failed:
        raise SystemExit(f"{label}: {len(failed)} frames failed, e.g. {failed[0].name}: {failed[0].message}")
    n = len(files)
    steady = (n - 1) / (stamps[-1] - stamps[0]) if n > 1 and stamps[-1] > stamps[0] else float("nan")
    fit_s = [o.value[1] for o in outcomes]
    return {
        "engine": label,
        "frames": n,
        "wall_s": round(wall, 3),
        "startup_s": round(stamps[0] - t0, 3),
        "frames_per_s": round(n / wall, 4),
        "steady_frames_per_s": round(steady, 4),
        "median_fit_s": round(float(np.median(fit_s)), 4),
    }


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--frames", type=int, default=24)
    ap.add_argument("--engines", default="1,2,ray", help="comma-separated: a number of workers, or 'ray'")
    ap.add_argument("--workers", type=int, default=2, help="CPUs of the local Ray")
    ap.add_argument("--ray-address", default="", help="a running cluster ('auto'); default: a local Ray")
    ap.add_argument("--hypotheses", type=int, default=None)
    ap.add_argument("--keep", type=Path, default=None, help="keep frames and outputs in this folder")
    ap.add_argument("--json", type=Path, default=None, help="also write the rows as JSON")
    args = ap.parse_args()

    from cuboidcli.fitting.config import FitConfig, resolve_device

    config = FitConfig(device=resolve_device("cpu"))
    if args.hypotheses is not None:
        config = replace(config, hypotheses=args.hypotheses)
    tmp = tempfile.TemporaryDirectory(prefix="bench_scaleout_")
    root = args.keep or Path(tmp.name)
    files = write_frames(root / "frames", args.frames)
    rows, cuboids = [], {}
    for engine in args.engines.split(","):
        if engine == "ray":
            label = f"ray ({args.ray_address or f'local, {args.workers} CPUs'})"
            row = run_engine(label, files, root / "out_ray", config, args.workers, args.ray_address)
            out = root / "out_ray"
        else:
            workers = int(engine)
            label = f"{workers} worker{'s' if workers > 1 else ''}"
            out = root / f"out_{workers}"
            row = run_engine(label, files, out, config, workers, None)
        rows.append(row)
        cuboids[row["engine"]] = [json.loads(p.read_text())["cuboids"] for p in sorted(out.glob("*.json"))]
        print(
            f"{row['engine']:<28} {row['frames']:>4} frames  wall {row['wall_s']:7.2f} s  start-up "
            f"{row['startup_s']:6.2f} s  {row['frames_per_s']:6.3f} frames/s  steady "
            f"{row['steady_frames_per_s']:6.3f} frames/s  median fit {row['median_fit_s']:.3f} s",
            flush=True,
        )
    same = all(c == next(iter(cuboids.values())) for c in cuboids.values())
    print(f"identical cuboids on every engine: {same}")
    if args.json is not None:
        args.json.write_text(
            json.dumps({"config": config.to_dict(), "rows": rows, "identical": same}, indent=1)
        )
    if not same:
        raise SystemExit("engines disagree")


if __name__ == "__main__":
    main()

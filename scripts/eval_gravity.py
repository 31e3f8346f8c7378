"""How well gravity is estimated from depth (geometry/gravity.py).

Synthetic frames know their gravity (``world_from_camera`` in cuboids/<name>.json): the error is the angle
between the estimated and the true up. Real frames have no ground truth; they are judged by their floor:
the points within 3 cm of the lowest large horizontal plane are fitted by least squares, and the angle
between that plane's normal and the estimate is reported.

    python scripts/eval_gravity.py --synthetic runs/synth --split test --limit 20 \\
        --real ../shared/data/nyu ../shared/data/tum
"""

from __future__ import annotations

import argparse
import json
from pathlib import Path

import numpy as np

from cuboidcli.evaluation.runner import load_frames
from cuboidcli.geometry.gravity import estimate_gravity


def _angle(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.rad2deg(np.arccos(np.clip(abs(a @ b), -1.0, 1.0))))


def floor_normal(points: np.ndarray, up: np.ndarray, band: float = 0.03) -> tuple[np.ndarray, int] | None:
    """Normal of the floor: the lowest height slice along ``up`` holding >= 5 % of the points, refitted."""
    h = points @ up
    edges = np.arange(h.min(), h.max() + band, band)
    counts, _ = np.histogram(h, edges)
    big = np.flatnonzero(counts >= 0.05 * len(points))
    if len(big) == 0:
        return None
    h0 = edges[big[0]] + band / 2
    sel = np.abs(h - h0) < band
    q = points[sel] - points[sel].mean(0)
    return np.linalg.svd(q, full_matrices=False)[2][2], int(sel.sum())


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--synthetic", type=Path)
    ap.add_argument("--split", default="test")
    ap.add_argument("--limit", type=int, default=20)
    ap.add_argument("--real", type=Path, nargs="*", default=[])
    args = ap.parse_args()
    if args.synthetic:
        frames, _ = load_frames(args.synthetic, args.split, limit=args.limit)
        errors = []
        for f in frames:
            gt = json.loads((args.synthetic / "cuboids" / f"{f.name}.json").read_text())
            up_true = np.array(gt["world_from_camera"])[2, :3]
            g = estimate_gravity(f.camera.backproject(f.depth_m(), 8))
            errors.append(np.nan if g is None else _angle(g.up, up_true))
        e = np.array(errors)
        print(
            f"synthetic {args.split}: {len(e)} frames, no estimate {int(np.isnan(e).sum())}, "
            f"median {np.nanmedian(e):.2f} deg, max {np.nanmax(e):.2f} deg, "
            f"within 2 deg {100 * np.mean(e < 2):.0f} %"
        )
    for folder in args.real:
        frames, _ = load_frames(folder, None)
        for f in frames:
            grid = f.camera.backproject(f.depth_m(), 4)
            pts = grid.reshape(-1, 3)
            pts = pts[pts[:, 2] > 0]
            g = estimate_gravity(f.camera.backproject(f.depth_m(), 8))
            if g is None:
                print(f"{f.name}: no reliable estimate")
                continue
            floor = floor_normal(pts, g.up)
            floor_txt = (
                "no floor in view"
                if floor is None
                else (f"floor plane ({floor[1]} points) at {_angle(floor[0], g.up):.2f} deg")
            )
            print(f"{f.name}: up {np.round(g.up, 3).tolist()}, confidence {g.confidence:.2f}, {floor_txt}")


if __name__ == "__main__":
    main()

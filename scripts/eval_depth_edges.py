"""Does dropping depth discontinuities (cuboidcli/depth/edges.py) before the fit give better cuboids?

    python scripts/eval_depth_edges.py --real ../shared/data/nyu ../shared/data/tum --synthetic /tmp/synth \\
        --runs 3 --variant 85/2 --variant 80/2 --variant 88/2 --variant 85/3 --picture /tmp/edges

For every frame the depth is predicted from its RGB image with the built-in network (each frame's
intrinsics), once. Cuboids are fitted with the default FitConfig (seeds 0..runs-1) to that depth as it is
("off") and with the edge pixels dropped (each --variant MAX_ANGLE_DEG/RADIUS), and every fit is scored
against the frame's TRUE depth with :func:`cuboidcli.evaluation.metrics.frame_metrics` (coverage, OA
distance of the covered points, AUC@20 cm / 5 cm, pooled over the frames of a run as the runner does; mean
+- std over the runs). ``--sensor`` also fits the true (sensor) depth itself with and without the drop (the
first variant), scored against the same true depth. Columns "drop %" (valid pixels dropped) and "AbsRel
kept / dropped" (error of the predicted depth against the true depth on the kept and the dropped pixels)
say what the mask removes, and "near true edge % dropped / all" the share of the dropped pixels (and, for
reference, of all pixels) that lie within 1 % of the image width of a discontinuity of the TRUE depth
(the default mask on the true depth): how well the mask on the prediction finds real object boundaries.
``--no-fit`` prints these columns only (no cuboids). ``--picture DIR`` writes DIR/<frame>_edges.png: the
RGB with the dropped pixels of the first variant in red, for the first --real frame (or --picture-frame
NAME).

Frames: all frames of every --real folder (pooled as "real") and of --synthetic (split --split, default
all; ``cuboids synth --count 10 --seed 3 -o DIR`` makes one). Prints one markdown table per data set.
"""

from __future__ import annotations

import argparse
import math
import shlex
import sys
import time
from dataclasses import replace
from pathlib import Path

import numpy as np

from cuboidcli.camera import valid_depth
from cuboidcli.depth import estimate_depth
from cuboidcli.depth.edges import depth_edge_mask
from cuboidcli.evaluation.aggregate import aggregate, mean_std
from cuboidcli.evaluation.metrics import frame_metrics
from cuboidcli.evaluation.runner import load_frames
from cuboidcli.factories import DepthModelOptions, depth_estimator
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import fit_depth
from cuboidcli.job import fitter_for

KEYS = (
    ("cuboids", "\\|M\\|", "{:.2f}"),
    ("coverage_pct", "coverage %", "{:.1f}"),
    ("oa_covered_cm", "OA cov. cm", "{:.1f}"),
    ("auc20cm_pct", "AUC@20 %", "{:.2f}"),
    ("auc5cm_pct", "AUC@5 %", "{:.2f}"),
)


def parse_variant(text: str) -> tuple[str, dict]:
    angle, _, radius = text.partition("/")
    return f"drop {text}", {"max_angle_deg": float(angle), "radius": int(radius or 2)}


def focal(camera) -> float:
    return math.sqrt(camera.fx * camera.fy)


def abs_rel(pred: np.ndarray, true: np.ndarray, where: np.ndarray) -> float:
    m = where & valid_depth(true) & valid_depth(pred)
    return float(np.mean(np.abs(pred[m] - true[m]) / true[m])) if m.any() else math.nan


def nanmean(values: list[float]) -> float:
    finite = [v for v in values if math.isfinite(v)]
    return float(np.mean(finite)) if finite else math.nan


def near_edges(true: np.ndarray, focal_px: float) -> np.ndarray:
    """Pixels within 1 % of the width of a discontinuity of the true depth (default mask)."""
    import cv2

    r = max(1, round(0.01 * true.shape[1]))
    edges = depth_edge_mask(true, focal_px).view(np.uint8)
    return cv2.dilate(edges, np.ones((2 * r + 1, 2 * r + 1), np.uint8)).view(bool)


def picture(rgb: np.ndarray, mask: np.ndarray, path: Path) -> None:
    import cv2

    out = rgb.copy()
    out[mask] = (255, 0, 0)
    path.parent.mkdir(parents=True, exist_ok=True)
    both = np.concatenate([rgb, out], axis=1)
    cv2.imwrite(str(path), cv2.cvtColor(both, cv2.COLOR_RGB2BGR))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--real", type=Path, nargs="*", default=[])
    ap.add_argument("--synthetic", type=Path, default=None)
    ap.add_argument("--split", default=None)
    ap.add_argument("--runs", type=int, default=3)
    ap.add_argument("--variant", action="append", default=[], help="MAX_ANGLE_DEG/RADIUS, e.g. 85/2")
    ap.add_argument("--sensor", action="store_true", help="also fit the true depth with / without the drop")
    ap.add_argument("--no-fit", action="store_true", help="mask statistics only, no cuboids")
    ap.add_argument("--picture", type=Path, default=None)
    ap.add_argument("--picture-frame", default=None)
    args = ap.parse_args()
    variants = [("off", None)] + [parse_variant(v) for v in args.variant or ["85/2"]]

    datasets = []
    if args.real:
        frames = []
        for folder in args.real:
            frames += load_frames(folder)[0]
        datasets.append(("real", frames))
    if args.synthetic is not None:
        datasets.append(("synthetic", load_frames(args.synthetic, args.split)[0]))
    estimator = depth_estimator(DepthModelOptions(None))
    seeds = list(range(args.runs))
    lines = [f"`{shlex.join(sys.orig_argv)}`", ""]
    for ds_name, frames in datasets:
        # rows: (input, variant) -> per run a list of FrameMetrics; extra per-row diagnostics
        rows: dict[tuple[str, str], list[list]] = {}
        diag: dict[tuple[str, str], dict[str, list[float]]] = {}
        for frame in frames:
            true = frame.depth_m()
            rgb = frame.rgb()
            pred, _ = estimate_depth(estimator, rgb, frame.camera)
            near_true_edge = near_edges(true, focal(frame.camera))
            inputs = [("rgb", pred)] + ([("sensor", true)] if args.sensor else [])
            for input_name, depth in inputs:
                for vname, params in variants if input_name == "rgb" else variants[:2]:
                    t = time.perf_counter()
                    if params is None:
                        mask = np.zeros(depth.shape, bool)
                    else:
                        mask = depth_edge_mask(depth, focal(frame.camera), **params)
                    fit_input = np.where(mask, 0.0, depth).astype(np.float32)
                    d = diag.setdefault(
                        (input_name, vname), {"drop": [], "kept": [], "dropped": [], "near": [], "base": []}
                    )
                    d["drop"].append(100.0 * mask.sum() / max(1, valid_depth(depth).sum()))
                    scored = valid_depth(true)
                    d["near"].append(100.0 * near_true_edge[mask & scored].mean() if mask.any() else math.nan)
                    d["base"].append(100.0 * near_true_edge[scored].mean())
                    if input_name == "rgb":
                        d["kept"].append(abs_rel(pred, true, ~mask))
                        d["dropped"].append(abs_rel(pred, true, mask))
                    if (
                        args.picture is not None
                        and input_name == "rgb"
                        and vname == variants[1][0]
                        and frame.name == (args.picture_frame or frames[0].name)
                    ):
                        picture(rgb, mask, args.picture / f"{frame.name}_edges.png")
                    per_run = rows.setdefault((input_name, vname), [[] for _ in seeds])
                    for r, seed in enumerate([] if args.no_fit else seeds):
                        config = FitConfig(seed=seed)
                        fitter = fitter_for(replace(config, seed=0), None, None)
                        cuboids, _ = fit_depth(
                            fit_input, frame.camera, config, solver=fitter.solver, sampler=fitter.sampler
                        )
                        per_run[r].append(frame_metrics(frame.name, true, frame.camera, cuboids))
                    print(
                        f"{ds_name} {frame.name} {input_name} {vname}: drop {d['drop'][-1]:.1f} %, "
                        f"{time.perf_counter() - t:.1f} s",
                        file=sys.stderr,
                        flush=True,
                    )
        header = ["input", "edges", "drop %", "AbsRel kept / dropped", "near true edge % dropped / all"]
        header += [] if args.no_fit else [h for _, h, _ in KEYS]
        runs = "no fits" if args.no_fit else f"{len(seeds)} seeds"
        lines += [f"### {ds_name}: {len(frames)} frames, {runs}", ""]
        lines += ["| " + " | ".join(header) + " |", "|---" * len(header) + "|"]
        for (input_name, vname), per_run in rows.items():
            summary = {} if args.no_fit else mean_std([aggregate(run, curves=False) for run in per_run])
            d = diag[(input_name, vname)]
            err = f"{nanmean(d['kept']):.3f} / {nanmean(d['dropped']):.3f}" if d["kept"] else ""
            near = f"{nanmean(d['near']):.0f} / {nanmean(d['base']):.0f}"
            cells = [input_name, vname, f"{np.mean(d['drop']):.1f}", err, near]
            for key, _, spec in [] if args.no_fit else KEYS:
                mean, std = summary.get(key, (math.nan, math.nan))
                cells.append(spec.format(mean) + (f" +- {std:.2f}" if key.startswith("auc") else ""))
            lines.append("| " + " | ".join(cells) + " |")
        lines.append("")
        print("\n".join(lines[-(len(rows) + 4) :]), file=sys.stderr, flush=True)
    print("\n".join(lines))


if __name__ == "__main__":
    main()

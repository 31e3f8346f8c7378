"""Whole rooms on synthetic room scans: the sequence's visibility against a bare cloud's and plain inlier
counting, and the Open3D planes + clusters baseline, in one table (docs/scenes.md).

    python benchmarks/eval_scenes.py --scenes 4 --views 8 --size 320x240

Each scene is rendered from ``--views`` poses (cuboidcli.synth.scan), written in the plain sequence
layout and fused as ``cuboids fit FOLDER`` fuses it; the methods fit the same fused points and are scored
on the scene's ground truth (cuboidcli.evaluation.scene).
"""

from __future__ import annotations

import argparse
import json
import tempfile
import time
from pathlib import Path

import numpy as np

from cuboidcli.api import Fitter
from cuboidcli.camera import Camera
from cuboidcli.evaluation.baseline import planes_and_clusters
from cuboidcli.evaluation.scene import aggregate_scenes, scene_metrics
from cuboidcli.fitting.scene import SceneConfig, fit_scene
from cuboidcli.io.sequence import fuse_sequence, read_sequence
from cuboidcli.synth.scan import generate_room_scan, read_scan_truth, write_room_scan

KEYS = (
    "n_cuboids",
    "auc20cm_pct",
    "auc5cm_pct",
    "object_recall_pct",
    "object_precision_pct",
    "object_box_recall_iou0.25_pct",
    "object_box_recall_iou0.5_pct",
    "shell_box_recall_iou0.25_pct",
    "seconds",
)


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("--scenes", type=int, default=4)
    ap.add_argument("--views", type=int, default=8)
    ap.add_argument("--size", default="320x240")
    ap.add_argument("--seed", type=int, default=1000)
    ap.add_argument("--json", type=Path, default=None)
    args = ap.parse_args()
    w, h = (int(v) for v in args.size.split("x"))
    camera = Camera.preset("nyu").scaled(w / 640, h / 480)
    fitter = Fitter()
    names = ("views (sequence)", "views (bare cloud)", "inside", "plain", "open3d planes+clusters")
    rows: dict[str, list[dict]] = {name: [] for name in names}
    with tempfile.TemporaryDirectory() as tmp:
        for i in range(args.scenes):
            root = write_room_scan(Path(tmp) / f"s{i}", generate_room_scan(args.seed + i, args.views, camera))
            gt, points, instance = read_scan_truth(root)
            cloud = fuse_sequence(read_sequence(root))
            runs = {
                "views (sequence)": ("views", cloud.viewpoints),
                "views (bare cloud)": ("views", None),
                "inside": ("inside", None),
                "plain": ("plain", None),
            }
            for name, (vis, views) in runs.items():
                t = time.perf_counter()
                scene = SceneConfig(visibility=vis)
                parts = {"solver": fitter.solver, "sampler": fitter.sampler, "viewpoints": views}
                cub, _ = fit_scene(cloud.points, fitter.config, scene, **parts)
                m = scene_metrics(cub, gt, points, instance)
                m["seconds"] = time.perf_counter() - t
                rows[name].append(m)
            t = time.perf_counter()
            base = planes_and_clusters(cloud.points, up=np.array([0.0, 0.0, 1.0]))
            m = scene_metrics(base, gt, points, instance)
            m["seconds"] = time.perf_counter() - t
            rows["open3d planes+clusters"].append(m)
            print(f"scene {i}: {len(cloud.points)} fused points", flush=True)
    table = {name: aggregate_scenes(r) for name, r in rows.items()}
    print("| method | " + " | ".join(KEYS) + " |")
    print("|---" * (len(KEYS) + 1) + "|")
    for name, agg in table.items():
        print(f"| {name} | " + " | ".join(f"{agg.get(k, float('nan')):.1f}" for k in KEYS) + " |")
    if args.json:
        args.json.write_text(json.dumps(table, indent=1, default=float))


if __name__ == "__main__":
    main()

"""Fit the embedded demo room for several seeds and report, per seed, the cuboids found and which of its
objects (floor, walls, sofa, cabinet, table, boxes) are explained (the object-recall rule of
`cuboids evaluate`: one cuboid holds >= 50 % of the object's pixels and >= 50 % of its own assigned pixels
lie on the object). The object of each pixel comes from rendering the room's ground-truth cuboids.

    python scripts/demo_objects.py [--seeds 20] [--hypotheses 1024] [--set FIELD=VALUE ...]
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.evaluation.object_recall import OBJECT_EXPLAIN_PCT
from cuboidcli.factories import make_sampler, make_solver
from cuboidcli.fitting.assign import assign_points
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import fit_depth
from cuboidcli.fitting.scoring import ScoreParams
from cuboidcli.io.depth import read_depth
from cuboidcli.io.result import read_result
from cuboidcli.synth import render_boxes

SAMPLE = Path(__file__).resolve().parents[1] / "cuboidcli" / "data" / "sample"


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("--seeds", type=int, default=20)
    ap.add_argument("--hypotheses", type=int, default=1024)
    ap.add_argument("--set", action="append", default=[], help="FIELD=VALUE (FitConfig)")
    args = ap.parse_args()
    from eval_proposals import parse_variant

    cam = json.loads((SAMPLE / "camera.json").read_text())
    camera = Camera(cam["fx"], cam["fy"], cam["cx"], cam["cy"], cam["width"], cam["height"])
    depth = read_depth(SAMPLE / "sample_depth.png", cam["depth_scale"])
    gt = json.loads((SAMPLE / "sample_cuboids.json").read_text())
    gt_cuboids = read_result(SAMPLE / "sample_cuboids.json").cuboids
    _, box_index = render_boxes(gt_cuboids, camera)
    box_object = np.array([0] + [c["object"] for c in gt["cuboids"]])
    names = {c["object"]: c["category"] for c in gt["cuboids"]}
    obj = box_object[box_index].ravel()
    pts = camera.backproject(depth).reshape(-1, 3)
    valid = pts[:, 2] > 0
    pts, obj = pts[valid], obj[valid]
    _, overrides = parse_variant("x:" + ",".join(args.set))
    config = replace(FitConfig(hypotheses=args.hypotheses), **overrides)
    solver, sampler = make_solver(config), make_sampler(config.sampler)
    counts = []
    explained_count: dict[int, int] = {}
    for seed in range(args.seeds):
        cuboids, info = fit_depth(depth, camera, replace(config, seed=seed), solver=solver, sampler=sampler)
        labels = assign_points(pts, cuboids, ScoreParams(config.tau_sq_m2, config.beta, config.tau_c, True))
        got = []
        for o in sorted(names):
            size = int((obj == o).sum())
            if size < 0.01 * obj.size:
                continue
            for k in range(len(cuboids)):
                joint = int(((obj == o) & (labels == k)).sum())
                if 100 * joint >= OBJECT_EXPLAIN_PCT * size and 100 * joint >= OBJECT_EXPLAIN_PCT * int(
                    (labels == k).sum()
                ):
                    got.append(f"{names[o]}#{o}")
                    explained_count[o] = explained_count.get(o, 0) + 1
                    break
        counts.append(len(cuboids))
        print(f"seed {seed:2d}: {len(cuboids)} cuboids, batches {info.batches}, explained: {', '.join(got)}")
    print(f"cuboids per seed: min {min(counts)}, mean {np.mean(counts):.2f}")
    for o, c in sorted(explained_count.items()):
        print(f"  {names[o]}#{o}: explained in {c} of {args.seeds} seeds")


if __name__ == "__main__":
    main()

"""Fit frames with given FitConfig overrides and stack their panels (image | depth | cuboids | labels)
into one PNG, to look at before believing a number.

    python scripts/panel_grid.py OUT.png DATA [DATA ...] [--limit N] [--split S] [--set FIELD=VALUE ...]
"""

from __future__ import annotations

import argparse
from dataclasses import replace

import numpy as np

from cuboidcli.evaluation.runner import load_frames
from cuboidcli.export.overlay import render_images, write_png
from cuboidcli.factories import make_sampler, make_solver
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import fit_depth


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("data", nargs="+")
    ap.add_argument("--limit", type=int, default=None)
    ap.add_argument("--split", default=None)
    ap.add_argument("--set", action="append", default=[], help="FIELD=VALUE (FitConfig)")
    ap.add_argument("--width", type=int, default=1600, help="width of each panel row, pixels")
    args = ap.parse_args()
    from eval_proposals import parse_variant

    _, overrides = parse_variant("x:" + ",".join(args.set))
    config = replace(FitConfig(), **overrides)
    solver, sampler = make_solver(config), make_sampler(config.sampler)
    rows = []
    for data in args.data:
        for frame in load_frames(data, args.split, limit=args.limit)[0]:
            depth = frame.depth_m()
            cuboids, info = fit_depth(depth, frame.camera, config, solver=solver, sampler=sampler)
            rgb = frame.rgb() if hasattr(frame, "rgb") else None
            if rgb is not None and rgb.shape[:2] != depth.shape:
                rgb = None
            panel = render_images(frame.camera, cuboids, rgb, depth)["panel"]
            import cv2

            h = int(panel.shape[0] * args.width / panel.shape[1])
            rows.append(cv2.resize(panel, (args.width, h), interpolation=cv2.INTER_AREA))
            print(frame.name, len(cuboids), info.batches, [round(g) for g in info.gains], flush=True)
    write_png(args.out, np.concatenate(rows, 0))


if __name__ == "__main__":
    main()

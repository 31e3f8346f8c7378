"""Free and aligned fits of the same frames side by side (image | free | gravity | manhattan overlays), one
row per frame, to judge upright boxes by looking. The embedded demo room comes first, then the frames of
each DATA folder (``--names`` keeps those frames).

    python scripts/align_compare.py OUT.png [DATA ...] [--names A,B] [--modes free,gravity,manhattan]
        [--width 1800] [--seed 0]
"""

from __future__ import annotations

import argparse
import json
from dataclasses import replace
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.evaluation.runner import load_frames
from cuboidcli.export.overlay import background_image, draw_overlay, make_panel, raycast, write_png
from cuboidcli.factories import make_sampler, make_solver
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import fit_depth
from cuboidcli.io.depth import read_depth

SAMPLE = Path(__file__).resolve().parents[1] / "cuboidcli" / "data" / "sample"


def demo_frame():
    cam = json.loads((SAMPLE / "camera.json").read_text())
    camera = Camera(cam["fx"], cam["fy"], cam["cx"], cam["cy"], cam["width"], cam["height"])
    return "demo room", read_depth(SAMPLE / "sample_depth.png", cam["depth_scale"]), camera, None


def main() -> None:
    ap = argparse.ArgumentParser()
    ap.add_argument("out")
    ap.add_argument("data", nargs="*")
    ap.add_argument("--names", default=None, help="comma-separated frame names to keep")
    ap.add_argument("--modes", default="free,gravity,manhattan")
    ap.add_argument("--width", type=int, default=1800, help="width of each row, pixels")
    ap.add_argument("--seed", type=int, default=0)
    args = ap.parse_args()
    import cv2

    modes = args.modes.split(",")
    frames = [demo_frame()]
    for data in args.data:
        names = args.names.split(",") if args.names else None
        for f in load_frames(data)[0]:
            if names and f.name not in names:
                continue
            rgb = f.rgb() if hasattr(f, "rgb") else None
            frames.append((f.name, f.depth_m(), f.camera, rgb))
    base = replace(FitConfig(), seed=args.seed)
    solver, sampler = make_solver(base), make_sampler(base.sampler)
    rows = []
    for name, depth, camera, rgb in frames:
        if rgb is not None and rgb.shape[:2] != depth.shape:
            rgb = None
        background = background_image(camera, rgb, depth)
        tiles = [(name, background)]
        for mode in modes:
            config = replace(base, align=mode)
            cuboids, info = fit_depth(depth, camera, config, solver=solver, sampler=sampler)
            overlay = draw_overlay(background, camera, cuboids, raycast(camera, cuboids))
            tiles.append((f"{info.align} ({len(cuboids)})", overlay))
            print(name, mode, info.align, len(cuboids), info.aligned, flush=True)
        panel = make_panel(tiles)
        h = int(panel.shape[0] * args.width / panel.shape[1])
        rows.append(cv2.resize(panel, (args.width, h), interpolation=cv2.INTER_AREA))
    write_png(args.out, np.concatenate(rows, 0))


if __name__ == "__main__":
    main()

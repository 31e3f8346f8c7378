"""Save the learned sampler's Q sampling-weight maps for a frame as one PNG (RGB | Sequential-RANSAC
weights | map 1..Q; each tile scaled to its own maximum), for the first
step (empty state) of the estimator, or with ``--after K`` for the step after K cuboids were selected (the
estimator runs with the learned sampler first). Used to inspect what the network attends to.

    python scripts/show_sampler_maps.py DATASET FRAME OUT.png [--weights DIR] [--after K]
"""

from __future__ import annotations

import argparse

import cv2
import numpy as np
import torch

from cuboidcli.factories import make_sampler, make_solver
from cuboidcli.fitting.prepare import prepare_points
from cuboidcli.io.atomic import atomic_write_bytes
from cuboidcli.io.dataset import list_frames
from cuboidcli.sampling import SamplingContext


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("dataset")
    ap.add_argument("frame")
    ap.add_argument("out")
    ap.add_argument("--weights", default=None)
    ap.add_argument("--after", type=int, default=0, help="show the maps after this many selected cuboids")
    args = ap.parse_args()
    frame = next(f for f in list_frames(args.dataset) if f.name == args.frame)
    depth = frame.depth_m()
    prep = prepare_points(depth, frame.camera, 8).as_tensors()  # the learned sampler weighs tensors
    sampler = make_sampler("learned", args.weights)
    state = torch.zeros(prep.points.shape[0])
    if args.after > 0:
        from cuboidcli.fitting.config import FitConfig
        from cuboidcli.fitting.pipeline import fit_depth

        config = FitConfig(sampler="learned", max_cuboids=args.after, hypotheses=1024)
        cuboids, info = fit_depth(depth, frame.camera, config, solver=make_solver(config), sampler=sampler)
        state = torch.from_numpy(info.state).float()
        print(f"state after {len(cuboids)} cuboid(s)")
    ctx = SamplingContext(prep.points, prep.grid.index, prep.grid.shape, prep.grid.depth, state, args.after)
    with torch.no_grad():
        p, q = sampler.distributions(ctx)
    hs, ws = prep.grid.shape
    h, w = depth.shape
    tiles = []
    rgb = frame.rgb()
    tiles.append(cv2.resize(rgb if rgb is not None else np.zeros((h, w, 3), np.uint8), (w // 2, h // 2)))
    prior = (1.0 - state.double().clamp(0.0, 1.0)).clamp_min(0.0)
    maps = [("prior (sequential)", prior / prior.sum())] + [
        (f"map {j + 1}  q={float(q[j]):.2f}", p[j]) for j in range(p.shape[0])
    ]
    for label, pj in maps:
        grid = np.zeros(hs * ws)
        grid[prep.grid.index.numpy()] = pj.numpy()
        img = (255 * grid / max(grid.max(), 1e-12)).reshape(hs, ws).astype(np.uint8)
        img = cv2.applyColorMap(
            cv2.resize(img, (w // 2, h // 2), interpolation=cv2.INTER_NEAREST), cv2.COLORMAP_INFERNO
        )[..., ::-1].copy()
        cv2.putText(
            img,
            label,
            (8, 22),
            cv2.FONT_HERSHEY_SIMPLEX,
            0.6,
            (255, 255, 255),
            1,
            cv2.LINE_AA,
        )
        tiles.append(img)
    ok, buf = cv2.imencode(".png", cv2.cvtColor(np.concatenate(tiles, axis=1), cv2.COLOR_RGB2BGR))
    atomic_write_bytes(args.out, buf.tobytes())
    print(f"wrote {args.out}")


if __name__ == "__main__":
    main()

"""Regenerate the README figures docs/demo_overlay.png and docs/demo.glb from a fitted demo result.

Usage (after ``cuboids fit`` has written a "cuboids/1" result of the demo scene):

    .venv/bin/python scripts/make_docs_figures.py out/demo.json [--image rgb.png] [--depth depth.png]

The RGB image and depth map default to the files the result records under ``input`` ("image", "depth"),
if they exist. The GLB holds the cuboids only unless ``--with-points`` is given (then every ``--step``-th
pixel's point), so that both files stay small enough for the repository.
"""

from __future__ import annotations

import argparse
from pathlib import Path

from cuboidcli.export import FittedData, write
from cuboidcli.export.overlay import render_images, write_png
from cuboidcli.io.depth import read_depth, read_rgb
from cuboidcli.io.result import read_result


def _recorded(result, key: str) -> Path | None:
    value = result.input.get(key)
    return Path(value) if isinstance(value, str) and Path(value).is_file() else None


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    ap.add_argument("result", type=Path, help="cuboids/1 result JSON of the demo scene")
    ap.add_argument(
        "--image", type=Path, default=None, help="RGB image (default: the one the result records)"
    )
    ap.add_argument(
        "--depth", type=Path, default=None, help="depth map (default: the one the result records)"
    )
    ap.add_argument("--depth-scale", type=float, default=None, help="metres per depth-PNG unit")
    ap.add_argument("--out-dir", type=Path, default=Path("docs"), help="where the figures go (default: docs)")
    ap.add_argument("--with-points", action="store_true", help="add the point cloud to the GLB")
    ap.add_argument("--step", type=int, default=8, help="pixel step of the GLB point cloud (default: 8)")
    args = ap.parse_args()

    result = read_result(args.result)
    image = args.image or _recorded(result, "image")
    depth = args.depth or _recorded(result, "depth")
    scale = args.depth_scale or float(result.input.get("depth_scale") or 0.001)
    rgb = read_rgb(image) if image is not None else None
    depth_m = read_depth(depth, scale) if depth is not None else None
    if args.with_points and depth_m is None:
        raise SystemExit("--with-points needs the depth map: pass --depth")

    overlay = render_images(result.camera, result.cuboids, rgb=rgb, depth_m=depth_m)["overlay"]
    fitted = FittedData.of_record(result, depth_m=depth_m, rgb=rgb)
    glb = write(fitted, None, (), with_points=args.with_points, point_step=args.step,
                paths={"glb": args.out_dir / "demo.glb"})["glb"]  # fmt: skip
    paths = [write_png(args.out_dir / "demo_overlay.png", overlay), glb]
    for p in paths:
        print(f"wrote {p} ({p.stat().st_size / 1024:.0f} KiB)")


if __name__ == "__main__":
    main()

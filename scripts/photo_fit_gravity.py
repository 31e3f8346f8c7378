"""How far the down direction of fits of the real photos is from the one their true depth gives.

For every "cuboids/1" result in the given folders whose name is a real frame of ../shared/data (the five
NYU frames and the TUM frame: ``basement_00000.json`` as ``cuboids evaluate --save-fits`` names it, or
``basement_00000_rgb_cuboids.json`` as ``cuboids fit basement_00000_rgb.jpg -o DIR/`` does), the angle between
its ``gravity.down`` and the down direction of the frame's true depth
(:func:`cuboidcli.geometry.gravity.estimate_gravity` on the depth back-projected with the true camera,
every 8th pixel), with the result's ``gravity.source`` and its focal length against the true one.

    for f in ../shared/data/nyu/*_rgb.* ../shared/data/tum/tum_rgb.png; do cuboids fit $f -o /tmp/fits/; done
    python scripts/photo_fit_gravity.py /tmp/fits [/tmp/eval/fits/seed0 ...]
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.geometry.gravity import estimate_gravity
from cuboidcli.io.depth import read_depth

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
NYU = ("basement_00000", "basement_00050", "basement_00100", "livingroom", "dining_crop")


def true_downs(data: Path) -> dict[str, tuple[np.ndarray, Camera]]:
    """Frame name -> (down of its true depth, true camera)."""
    out = {}
    nyu = json.loads((data / "nyu" / "cameras.json").read_text())
    frames = [
        (n, data / "nyu" / (f"{n}_depth_filled.png" if n == "dining_crop" else f"{n}_depth.png"),
         Camera.from_dict(nyu[n]), 0.001)
        for n in NYU
    ]  # fmt: skip
    tum = Camera.from_dict(json.loads((data / "tum" / "camera.json").read_text()))
    frames.append(("tum", data / "tum" / "tum_depth.png", tum, 2e-4))
    for name, depth, cam, scale in frames:
        g = estimate_gravity(cam.backproject(read_depth(depth, scale), 8))
        out[name] = (g.down, cam)
    return out


def angle_deg(a, b) -> float:
    a, b = np.asarray(a, float), np.asarray(b, float)
    return math.degrees(math.acos(float(np.clip(a @ b / np.linalg.norm(a) / np.linalg.norm(b), -1, 1))))


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("folders", type=Path, nargs="+")
    ap.add_argument("--data", type=Path, default=DATA)
    args = ap.parse_args()
    truth = true_downs(args.data)
    for folder in args.folders:
        errors = []
        print(f"{folder}:")
        for path in sorted(folder.glob("*.json")):
            name = path.stem.removesuffix("_cuboids").removesuffix("_rgb")
            if name not in truth:
                continue
            down, cam = truth[name]
            result = json.loads(path.read_text())
            gravity = result.get("gravity")
            err = math.nan if gravity is None else angle_deg(gravity["down"], down)
            errors.append(err)
            fx = result["camera"]["fx"]
            print(
                f"  {name:16s} {err:6.2f} deg  source {gravity['source'] if gravity else '-':16s} "
                f"fx {fx:6.1f} ({100 * (fx / cam.fx - 1):+.0f} % of {cam.fx:.1f}): "
                f"{result['input'].get('intrinsics_source') or '-'}"
            )
        finite = [e for e in errors if math.isfinite(e)]
        if not finite:
            print("  no fits of the real frames here: fit them first (cuboids fit PHOTO -o DIR/)")
            continue
        print(
            f"  within 5 deg: {sum(e <= 5.0 for e in finite)}/{len(errors)}; "
            f"range {min(finite):.2f}-{max(finite):.2f}, median {float(np.median(finite)):.2f}"
        )


if __name__ == "__main__":
    main()

"""How well a photo's lines give its down direction and its focal length (geometry/vanishing.py).

For each real RGB-D frame in ../shared/data (the NYU frames, the TUM frame, the Redwood colour images), the
photo alone goes through :func:`cuboidcli.geometry.vanishing.estimate_from_lines` (no intrinsics, the
principal point at the image centre) and is compared with its true depth map:

- down: the angle between the lines' down direction and the one estimated from the true depth
  (:func:`cuboidcli.geometry.gravity.estimate_gravity` on the depth back-projected with the true camera);
  also with the true intrinsics given (``known K``);
- focal: the estimated fx against the true one, on the full frame and on its central 480x360 crop (a
  crop keeps the focal length in pixels);
- rot90: the down direction of the photo turned by 90 degrees (np.rot90, the up hint turned with it),
  mapped back, against that of the photo as stored;
- the time per photo, and that of a 12 MP photo (an NYU frame scaled to 4000x3000);
- the focal length ``cuboids fit`` takes for the photo alone (no -K, no EXIF): the lines' when their
  confidence reaches ``load.camera.FOCAL_SURE``, else the default field of view (the built-in depth network
  predicts none) unless the lines rule it out (then their unsure estimate), on the full frame and on the
  crop.

With ``--seeds N``, the focal lengths of the photos and their crops are estimated again with RANSAC
seeds 0..N-1, and with ``--synth M`` of M synthetic rooms too (:mod:`cuboidcli.synth`, seeds 0..M-1, the
NYU camera, 640x480, and their 480x360 centre crops; ``--crops``: also centre crops of 560x420, 520x390
and 400x300 and 480x360 crops 20 px right and 15 up of the centre and the reverse): per group, the
estimates within 10 %, those the fit would take (confidence from FOCAL_SURE) right and wrong, the highest
confidence of a wrong one, and the fx the fit takes within 10 % (by where it came from).

    python scripts/eval_photo_lines.py [--data ../shared/data] [--draw /tmp] [--seeds 4] [--synth 40]
        [--crops]

``--draw DIR`` writes DIR/vp_<name>.png: the segments coloured by the vanishing point they support (red:
vertical, green and blue: horizontal, grey: none).
"""

from __future__ import annotations

import argparse
import json
import math
import time
from pathlib import Path

import cv2
import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.geometry.gravity import estimate_gravity
from cuboidcli.geometry.lines import detect_segments
from cuboidcli.geometry.vanishing import LineEstimate, estimate_from_lines
from cuboidcli.io.depth import read_depth, read_rgb
from cuboidcli.io.photo import default_camera
from cuboidcli.load.camera import FOCAL_SURE, default_for, from_lines

DATA = Path(__file__).resolve().parents[2] / "shared" / "data"
CROP = (480, 360)


def frames(data: Path) -> list[tuple[str, Path, Path, Camera, float]]:
    """(name, rgb, depth, true camera, depth scale) of every real frame with an RGB image."""
    out = []
    nyu = json.loads((data / "nyu" / "cameras.json").read_text())
    for name in ("basement_00000", "basement_00050", "basement_00100", "livingroom", "dining_crop"):
        rgb = next((data / "nyu").glob(f"{name}_rgb.*"))
        depth = data / "nyu" / (f"{name}_depth_filled.png" if name == "dining_crop" else f"{name}_depth.png")
        out.append((f"nyu/{name}", rgb, depth, Camera.from_dict(nyu[name]), 0.001))
    tum = Camera.from_dict(json.loads((data / "tum" / "camera.json").read_text()))
    out.append(("tum", data / "tum" / "tum_rgb.png", data / "tum" / "tum_depth.png", tum, 2e-4))
    redwood = Camera(525.0, 525.0, 319.5, 239.5, 640, 480)
    for rgb in sorted((data / "redwood" / "color").glob("*.jpg")):
        depth = data / "redwood" / "depth" / f"{rgb.stem}.png"
        out.append((f"redwood/{rgb.stem}", rgb, depth, redwood, 0.001))
    return out


def angle_deg(a: np.ndarray, b: np.ndarray) -> float:
    return math.degrees(math.acos(min(1.0, float(np.dot(a, b)))))


def rotated_down(rgb: np.ndarray) -> np.ndarray | None:
    """The down direction of the photo turned 90 degrees counter-clockwise, in the stored photo's camera
    frame. np.rot90 maps a stored pixel's ray (x, y, z) to (y, -x, z) (principal point at the centre)."""
    est = estimate_from_lines(np.ascontiguousarray(np.rot90(rgb)), up_hint=np.array([-1.0, 0.0, 0.0]))
    if est is None:
        return None
    d = est.down
    return np.array([-d[1], d[0], d[2]])


def timed(fn, repeat: int = 3):
    """(fn's result, median wall seconds, median CPU seconds of this process over ``repeat`` runs). On a
    shared machine the wall time includes waiting for a core; the CPU time is the work itself."""
    wall, cpu, out = [], [], None
    for _ in range(repeat):
        t, c = time.perf_counter(), time.process_time()
        out = fn()
        wall.append(time.perf_counter() - t)
        cpu.append(time.process_time() - c)
    return out, float(np.median(wall)), float(np.median(cpu))


def draw(rgb: np.ndarray, est: LineEstimate, path: Path) -> None:
    img = cv2.cvtColor(rgb, cv2.COLOR_RGB2BGR) // 2
    segs = detect_segments(rgb)
    vertical = int(np.abs(est.fit.rotation.T @ est.axes[:, 0]).argmax())
    colours = {vertical: (0, 0, 255)}
    for k, c in zip([a for a in range(3) if a != vertical], [(0, 200, 0), (255, 80, 0)], strict=True):
        colours[k] = c
    for s, label in zip(segs, est.fit.labels, strict=True):
        p, q = tuple(int(round(v)) for v in s[:2]), tuple(int(round(v)) for v in s[2:])
        cv2.line(img, p, q, colours.get(int(label), (128, 128, 128)), 2)
    cv2.imwrite(str(path), img)


def measure(name: str, rgb: np.ndarray, depth_m: np.ndarray, cam: Camera) -> tuple[dict, LineEstimate | None]:
    """One photo's row of the table, and its estimate."""
    g = estimate_gravity(cam.backproject(depth_m, 8))
    est, wall, cpu = timed(lambda: estimate_from_lines(rgb))
    known = estimate_from_lines(rgb, cam.fx, cam.fy, cam.cx, cam.cy)
    rot = rotated_down(rgb)
    h, w = rgb.shape[:2]
    crop = None
    if w >= CROP[0] and h >= CROP[1]:
        y0, x0 = (h - CROP[1]) // 2, (w - CROP[0]) // 2
        crop = estimate_from_lines(np.ascontiguousarray(rgb[y0 : y0 + CROP[1], x0 : x0 + CROP[0]]))
    row = {
        "name": name,
        "down": math.nan if est is None or g is None else angle_deg(est.down, g.down),
        "down_conf": 0.0 if est is None else est.down_confidence,
        "known": math.nan if known is None or g is None else angle_deg(known.down, g.down),
        "rot90": math.nan if est is None or rot is None else angle_deg(est.down, rot),
        "fx": cam.fx,
        "full": None if est is None else est.focal_px,
        "full_conf": 0.0 if est is None else est.focal_confidence,
        "crop": None if crop is None else crop.focal_px,
        "crop_conf": 0.0 if crop is None else crop.focal_confidence,
        "full_default": default_camera(w, h).fx,
        "crop_default": default_camera(*CROP).fx,
        "full_used": fit_focal(est, w, h),
        "crop_used": fit_focal(crop, *CROP),
        "segments": 0 if est is None else est.n_segments,
        "ms": 1000 * wall,
        "cpu_ms": 1000 * cpu,
    }
    return row, est


HEADER = (
    f"{'photo':22s} {'down':>6s} {'conf':>5s} {'known K':>7s} {'rot90':>6s} | {'fx true':>7s} "
    f"{'fx full':>13s} {'conf':>5s} {'used':>15s} | {'fx crop':>13s} {'conf':>5s} {'used':>15s} | "
    f"{'segs':>4s} {'ms':>4s} {'cpu':>4s}"
)


def fit_focal(est: LineEstimate | None, width: int, height: int) -> tuple[float, str]:
    """(fx, source) ``cuboids fit`` takes for a photo without -K or EXIF, as load.camera decides it: the
    lines' from a focal confidence of FOCAL_SURE ("lines"), else the default field of view ("default")
    unless the lines rule it out ("ruled out": then the lines' unsure estimate)."""
    camera = from_lines(est, width, height)
    if camera is not None:
        return camera.fx, "lines"
    camera = default_for(width, height, [], est)
    return camera.fx, "default" if camera.source == default_camera(width, height).source else "ruled out"


def used_focal(r: dict, key: str) -> tuple[float, str]:
    """(fx, source) ``cuboids fit`` takes for the photo (``key`` "full" or "crop") without -K or EXIF."""
    return r[key + "_used"]


def format_row(r: dict) -> str:
    def focal(f):
        return f"{'-':>13s}" if f is None else f"{f:6.0f} ({100 * (f / r['fx'] - 1):+4.0f}%)"

    def used(key):
        f, source = used_focal(r, key)
        return f"{f:4.0f} {100 * (f / r['fx'] - 1):+4.0f}% {source[0]}"  # l, d or r (ruled out)

    return (
        f"{r['name']:22s} {r['down']:6.2f} {r['down_conf']:5.2f} {r['known']:7.2f} {r['rot90']:6.2f} | "
        f"{r['fx']:7.1f} {focal(r['full'])} {r['full_conf']:5.2f} {used('full'):>15s} | {focal(r['crop'])} "
        f"{r['crop_conf']:5.2f} {used('crop'):>15s} | {r['segments']:4d} {r['ms']:4.0f} {r['cpu_ms']:4.0f}"
    )


def main() -> None:
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--data", type=Path, default=DATA)
    ap.add_argument("--draw", type=Path, default=None, help="write vp_<name>.png drawings here")
    ap.add_argument("--seeds", type=int, default=0, help="estimate the focal lengths with this many seeds")
    ap.add_argument("--synth", type=int, default=0, help="and on this many synthetic rooms (with --seeds)")
    ap.add_argument("--crops", action="store_true", help="with --seeds: crops of other sizes and places too")
    args = ap.parse_args()
    if not (args.data / "nyu").is_dir():
        raise SystemExit(f"no real frames in {args.data}")
    print(
        "down: degrees from the true depth's down; conf: confidence; used: the fx cuboids fit takes (l: the "
        "lines', d: the default field of view); ms / cpu: wall / CPU time per photo"
    )
    print(HEADER)
    rows = []
    for name, rgb_path, depth_path, cam, scale in frames(args.data):
        rgb = read_rgb(rgb_path)
        row, est = measure(name, rgb, read_depth(depth_path, scale), cam)
        rows.append(row)
        print(format_row(row))
        if args.draw is not None and est is not None:
            draw(rgb, est, args.draw / f"vp_{name.replace('/', '_')}.png")
    summary(rows)
    time_12mp(read_rgb(next((args.data / "nyu").glob("basement_00000_rgb.*"))))
    if args.seeds:
        photos = [(name, read_rgb(rgb), cam.fx) for name, rgb, _, cam, _ in frames(args.data)]
        crops = CROPS if args.crops else [CROPS[0], CROPS[3]]
        focal_over_seeds("real", photos, args.seeds, crops)
        if args.synth:
            focal_over_seeds("synthetic", synthetic_rooms(args.synth), args.seeds, crops)


def synthetic_rooms(n: int) -> list[tuple[str, np.ndarray, float]]:
    """(name, RGB, true fx) of n rendered synthetic rooms seen by the NYU camera (principal point at the
    image centre, as the lines assume)."""
    from cuboidcli.synth.scene import generate_scene

    camera = Camera(518.8579, 518.8579, 319.5, 239.5, 640, 480)
    return [(f"synth/{seed}", generate_scene(seed, camera).rgb, camera.fx) for seed in range(n)]


#: The cuts of ``--crops``: (label, width, height, dx, dy), the crop moved by (dx, dy) pixels from the
#: centre; width 0 is the whole frame.
CROPS = [
    ("full", 0, 0, 0, 0),
    ("560x420", 560, 420, 0, 0),
    ("520x390", 520, 390, 0, 0),
    ("480x360", 480, 360, 0, 0),
    ("400x300", 400, 300, 0, 0),
    ("480x360 +20-15", 480, 360, 20, -15),
    ("480x360 -20+15", 480, 360, -20, 15),
]


def cut(rgb: np.ndarray, width: int, height: int, dx: int = 0, dy: int = 0) -> np.ndarray | None:
    """The width x height part of the image moved by (dx, dy) from its centre; width 0: the image."""
    if width == 0:
        return rgb
    h, w = rgb.shape[:2]
    if w < width or h < height:
        return None
    x0 = min(max((w - width) // 2 + dx, 0), w - width)
    y0 = min(max((h - height) // 2 + dy, 0), h - height)
    return np.ascontiguousarray(rgb[y0 : y0 + height, x0 : x0 + width])


def focal_over_seeds(group: str, photos: list[tuple[str, np.ndarray, float]], seeds: int, crops) -> None:
    """One line per cut (``crops``: rows of CROPS): the lines' estimates within 10 %, those sure enough for
    the fit (confidence from FOCAL_SURE) right / wrong and the most confident wrong one, and the fit's fx
    (:func:`fit_focal`) within 10 %: in all, and from the sure lines, the lines ruling out the default and
    the default (right / taken), over RANSAC seeds 0..seeds-1."""
    for label, *spec in crops:
        n = within = right = wrong = 0
        worst = (0.0, "-")
        fit_ok = {"lines": [0, 0], "ruled out": [0, 0], "default": [0, 0]}
        for name, rgb, fx in photos:
            img = cut(rgb, *spec)
            if img is None:
                continue
            for seed in range(seeds):
                est = estimate_from_lines(img, seed=seed)
                n += 1
                f_fit, source = fit_focal(est, img.shape[1], img.shape[0])
                fit_ok[source][0] += abs(f_fit / fx - 1) <= 0.10
                fit_ok[source][1] += 1
                if est is None or est.focal_px is None:
                    continue
                ok = abs(est.focal_px / fx - 1) <= 0.10
                within += ok
                right += ok and est.focal_confidence >= FOCAL_SURE
                wrong += not ok and est.focal_confidence >= FOCAL_SURE
                if not ok and est.focal_confidence > worst[0]:
                    off = 100 * (est.focal_px / fx - 1)
                    worst = (est.focal_confidence, f"{name} seed {seed}, {off:+.0f} %")
        fit_within = sum(v[0] for v in fit_ok.values())
        by_source = ", ".join(f"{k} {v[0]}/{v[1]}" for k, v in fit_ok.items())
        print(
            f"{group} {label}, seeds 0-{seeds - 1}: lines' fx within 10 % {within}/{n}; confidence >= "
            f"{FOCAL_SURE:g}: {right} right, {wrong} wrong (most confident wrong {worst[0]:.2f}, "
            f"{worst[1]}); the fit's fx within 10 % {fit_within}/{n} ({by_source})"
        )


def summary(rows: list[dict]) -> None:
    def within(key, bound):
        vals = [r[key] for r in rows if np.isfinite(r[key])]
        return f"{sum(v <= bound for v in vals)}/{len(rows)}"

    def focal_within(key, bound=0.10):
        ok = [r[key] is not None and abs(r[key] / r["fx"] - 1) <= bound for r in rows]
        confident = [r for r in rows if r[key + "_conf"] >= 0.5]
        ok_conf = sum(abs(r[key] / r["fx"] - 1) <= bound for r in confident)
        return f"{sum(ok)}/{len(rows)} (confidence >= 0.5: {ok_conf} of {len(confident)} right)"

    print(f"down within 5 deg of the depth's: {within('down', 5.0)}; with the true K: {within('known', 5.0)}")
    print(f"rot90 within 3 deg: {within('rot90', 3.0)}")
    print(f"fx within 10 %: full frame {focal_within('full')}; 480x360 crop {focal_within('crop')}")

    def used_within(key, bound=0.10):
        """The fit's fx: the lines' from FOCAL_SURE, else the default field of view."""
        used = [used_focal(r, key) for r in rows]
        good = sum(abs(f / r["fx"] - 1) <= bound for (f, _), r in zip(used, rows, strict=True))
        lines = sum(s == "lines" for _, s in used)
        ruled = sum(s == "ruled out" for _, s in used)
        return f"{good}/{len(rows)} ({lines} from the sure lines, {ruled} from lines ruling out the default)"

    print(
        f"the fit's fx (lines from confidence {FOCAL_SURE:g}, else the default field of view unless the "
        f"lines rule it out) within 10 %: full frame {used_within('full')}; 480x360 crop "
        f"{used_within('crop')}"
    )


def time_12mp(rgb: np.ndarray) -> None:
    big = cv2.resize(rgb, (4000, 3000), interpolation=cv2.INTER_LINEAR)
    estimate_from_lines(big)  # warm up
    _, seg_wall, seg_cpu = timed(lambda: detect_segments(big), 5)
    _, wall, cpu = timed(lambda: estimate_from_lines(big), 5)
    print(
        f"12 MP (4000x3000), median of 5: segments {1000 * seg_wall:.0f} ms ({1000 * seg_cpu:.0f} ms CPU), "
        f"all {1000 * wall:.0f} ms ({1000 * cpu:.0f} ms CPU)"
    )


if __name__ == "__main__":
    main()

"""Line segments, Manhattan vanishing points, and the down direction and focal length they give
(geometry/lines.py, geometry/vp_model.py, geometry/manhattan_vp.py, geometry/vanishing.py)."""

from __future__ import annotations

import json
import math
import time

import cv2
import numpy as np
import pytest

from cuboidcli.geometry.lines import detect_segments
from cuboidcli.geometry.manhattan_vp import fit_manhattan
from cuboidcli.geometry.vanishing import estimate_from_lines
from cuboidcli.load.camera import FOCAL_SURE
from tests.conftest import SHARED_DATA


def _axis_rotation(axis: int, angle_deg: float) -> np.ndarray:
    c, s = math.cos(math.radians(angle_deg)), math.sin(math.radians(angle_deg))
    i, j = [(1, 2), (2, 0), (0, 1)][axis]
    r = np.eye(3)
    r[i, i], r[i, j], r[j, i], r[j, j] = c, -s, s, c
    return r


def _box_edges(lo, hi) -> list[tuple[np.ndarray, np.ndarray]]:
    """The 12 edges of an axis-aligned box (world coordinates)."""
    corners = np.array([[x, y, z] for x in (lo[0], hi[0]) for y in (lo[1], hi[1]) for z in (lo[2], hi[2])])
    return [(corners[a], corners[b]) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]


def _clip(p, q, w, h):
    """The part of the 2D segment p-q inside a w x h image (Liang-Barsky), or None."""
    t0, t1, d = 0.0, 1.0, q - p
    for den, num in ((-d[0], p[0]), (d[0], w - 1 - p[0]), (-d[1], p[1]), (d[1], h - 1 - p[1])):
        if abs(den) < 1e-12:
            if num < 0:
                return None
        elif den < 0:
            t0 = max(t0, num / den)
        else:
            t1 = min(t1, num / den)
    return None if t0 >= t1 else (p + t0 * d, p + t1 * d)


def render_room(fx, pitch_deg, roll_deg, yaw_deg, size=(640, 480), seed=0):
    """A line drawing of a room (its edges, floor tiles, doors and pictures on two walls, furniture boxes,
    short clutter strokes in random directions) on a blurred noise texture, seen from 1.4 m above the
    floor with the principal point at the image centre.

    World: z up, the room's walls along x and y. The camera looks along world +y turned by ``yaw_deg``
    about z, pitched by ``pitch_deg`` (negative: down) and rolled by ``roll_deg``. Returns (RGB image
    (H, W, 3) uint8, down (3,) in camera coordinates).
    """
    rng = np.random.default_rng(seed)
    w, h = size
    img = rng.normal(128, 40, (h // 8, w // 8, 3)).clip(0, 255).astype(np.uint8)
    img = cv2.GaussianBlur(cv2.resize(img, (w, h), interpolation=cv2.INTER_CUBIC), (0, 0), 3)
    base = np.array([[1.0, 0.0, 0.0], [0.0, 0.0, 1.0], [0.0, -1.0, 0.0]])  # camera x, y, z -> world x, -z, y
    tilt = _axis_rotation(0, pitch_deg) @ _axis_rotation(2, roll_deg)
    world_from_cam = _axis_rotation(2, yaw_deg) @ base @ tilt
    cam_pos = np.array([0.2, -1.0, 1.4])
    segments = _box_edges(np.array([-2.6, -3.0, 0.0]), np.array([2.8, 4.5, 2.6]))
    for t in np.arange(-2.5, 2.8, 0.5):  # floor tiles
        segments.append((np.array([t, -3.0, 0.0]), np.array([t, 4.5, 0.0])))
    for t in np.arange(-2.5, 4.5, 0.5):
        segments.append((np.array([-2.6, t, 0.0]), np.array([2.8, t, 0.0])))
    for _ in range(8):  # furniture
        c = np.array([rng.uniform(-2.0, 2.2), rng.uniform(0.5, 4.0), 0.0])
        half = np.array([rng.uniform(0.2, 0.6), rng.uniform(0.2, 0.5), 0.0])
        segments += _box_edges(c - half, c + half + np.array([0.0, 0.0, rng.uniform(0.4, 1.8)]))
    for _ in range(5):  # doors, windows and pictures on the back and left walls
        u0, z0, du, dz = rng.uniform((-2.0, 0.0, 0.4, 0.4), (1.6, 1.4, 1.0, 1.0))
        v0 = rng.uniform(-2.5, 3.0)
        segments += _box_edges(np.array([u0, 4.5, z0]), np.array([u0 + du, 4.5, z0 + dz]))
        segments += _box_edges(np.array([-2.6, v0, z0]), np.array([-2.6, v0 + du, z0 + dz]))
    for _ in range(40):  # clutter
        p = np.array([rng.uniform(-2.0, 2.4), rng.uniform(0.5, 4.0), rng.uniform(0.0, 2.0)])
        segments.append((p, p + rng.normal(0, 0.15, 3)))
    k = np.array([[fx, 0, (w - 1) / 2], [0, fx, (h - 1) / 2], [0, 0, 1.0]])
    for a, b in segments:
        pa, pb = world_from_cam.T @ (a - cam_pos), world_from_cam.T @ (b - cam_pos)
        if min(pa[2], pb[2]) < 0.1:  # clip at the near plane
            if max(pa[2], pb[2]) < 0.1:
                continue
            q = pa + (0.1 - pa[2]) / (pb[2] - pa[2]) * (pb - pa)
            pa, pb = (q, pb) if pa[2] < 0.1 else (pa, q)
        ua, ub = k @ pa, k @ pb
        clipped = _clip(ua[:2] / ua[2], ub[:2] / ub[2], w, h)
        if clipped is None:
            continue
        colour = rng.integers(0, 60, 3) if rng.random() < 0.5 else rng.integers(200, 256, 3)
        p1, p2 = (tuple(int(v) for v in np.round(q * 16)) for q in clipped)  # 4 fractional bits
        cv2.line(img, p1, p2, tuple(int(c) for c in colour), 2, cv2.LINE_AA, 4)
    img = (img + rng.normal(0, 3, img.shape)).clip(0, 255).astype(np.uint8)
    down = world_from_cam.T @ np.array([0.0, 0.0, -1.0])
    return img, down


def _angle(a, b) -> float:
    """Degrees between two unit vectors."""
    return math.degrees(math.acos(min(1.0, float(np.dot(a, b)))))


def _rot90_down(rgb: np.ndarray) -> np.ndarray:
    """The down direction of the image turned 90 degrees counter-clockwise (np.rot90), with the up hint
    turned with it, mapped back to the stored image's camera frame: a stored pixel's ray (x, y, z) is
    (y, -x, z) in the turned image (principal point at the centre)."""
    est = estimate_from_lines(np.ascontiguousarray(np.rot90(rgb)), up_hint=np.array([-1.0, 0.0, 0.0]))
    assert est is not None
    return np.array([-est.down[1], est.down[0], est.down[2]])


ROOMS = [  # fx (px), pitch, roll, yaw (degrees)
    (500.0, -15.0, 0.0, 30.0),
    (400.0, -25.0, 5.0, 20.0),
    (800.0, -10.0, -3.0, 40.0),
    (350.0, -30.0, 0.0, 35.0),
]


@pytest.mark.parametrize("fx,pitch,roll,yaw", ROOMS)
def test_a_rendered_room_gives_down_and_focal(fx, pitch, roll, yaw):
    img, down = render_room(fx, pitch, roll, yaw, seed=int(fx))
    est = estimate_from_lines(img)
    assert est is not None
    assert _angle(est.down, down) < 2.0
    assert est.focal_px == pytest.approx(fx, rel=0.05)
    assert est.down_confidence > 0.5 and est.focal_confidence > 0.5
    # the room's axes: up = -down, two horizontals, exactly orthonormal and right-handed
    assert np.allclose(est.axes.T @ est.axes, np.eye(3), atol=1e-9)
    assert np.linalg.det(est.axes) == pytest.approx(1.0)
    assert np.allclose(est.axes[:, 0], -est.down)
    assert est.down[1] > 0  # a camera pitched down by less than 90 degrees still sees down as +y
    known = estimate_from_lines(img, fx, fx)
    assert known is not None and known.focal_px is None and known.focal_confidence == 0.0
    assert _angle(known.down, down) < 2.0
    json.dumps(est.to_dict())


@pytest.mark.parametrize("seed", [1, 2])
def test_a_centre_crop_keeps_the_focal_length_in_pixels(seed):
    """A 480x360 crop of a 640x480 room photo has its field of view but the same fx: the lines must find
    it, not the focal length of a typical field of view across the crop."""
    img, down = render_room(519.0, -15.0, 0.0, 20.0, seed=seed)
    est = estimate_from_lines(np.ascontiguousarray(img[60:420, 80:560]))
    assert est is not None
    assert est.focal_px == pytest.approx(519.0, rel=0.05)  # measured: within 0.5 %
    assert est.focal_confidence >= FOCAL_SURE  # measured: 0.83-0.87
    assert _angle(est.down, down) < 2.0


def test_a_level_camera_facing_a_wall_fixes_down_but_not_the_focal_length():
    # every vanishing point but one at infinity: orthogonality says nothing about f
    img, down = render_room(520.0, 0.0, 0.0, 0.0, seed=4)
    est = estimate_from_lines(img)
    assert est is not None
    assert _angle(est.down, down) < 1.0 and est.down_confidence > 0.5
    assert est.focal_px is None or est.focal_confidence < 0.1


@pytest.mark.parametrize(
    "image",
    [
        np.full((480, 640, 3), 180, np.uint8),  # a plain wall
        np.random.default_rng(0).integers(0, 256, (480, 640, 3)).astype(np.uint8),  # noise
        np.full((8, 8, 3), 90, np.uint8),
        np.full((480, 640), 30, np.uint8),  # grey
        np.full((3, 5000, 3), 200, np.uint8),  # a sliver: nothing left once shrunk to 640 wide
        np.kron(np.arange(640) // 20 % 2 * 255, np.ones((480, 1))).astype(np.uint8),  # one family of edges
    ],
    ids=["plain", "noise", "tiny", "grey", "sliver", "stripes"],
)
def test_an_image_without_lines_gives_no_estimate(image):
    est = estimate_from_lines(image)
    assert est is None or (est.down_confidence < 0.2 and est.focal_confidence < 0.2)
    default_fx = 0.5 * max(image.shape[:2]) / math.tan(math.radians(31.5))
    assert est is None or not est.rules_out(default_fx)  # the default field of view stays


def test_random_strokes_give_low_confidence():
    rng = np.random.default_rng(1)
    img = np.full((480, 640, 3), 120, np.uint8)
    for _ in range(150):
        p = rng.uniform(0, (640, 480))
        q = p + rng.normal(0, 60, 2)
        colour = tuple(int(c) for c in rng.integers(0, 256, 3))
        cv2.line(img, tuple(int(v) for v in p), tuple(int(v) for v in q), colour, 2, cv2.LINE_AA)
    est = estimate_from_lines(img)
    assert est is not None  # segments but no common directions
    assert est.down_confidence < 0.2 and est.focal_confidence < 0.2
    # nor do they rule out a focal length, though their profile has a sharp minimum (at 682 px, 3.3
    # segments' worth below the default's 522 px, spread 0.04)
    assert est.coherence == 0.0 and not est.rules_out(522.2)


def test_turning_the_image_by_90_degrees_keeps_down():
    img, down = render_room(500.0, -20.0, 8.0, 35.0, seed=7)
    est = estimate_from_lines(img)
    assert est is not None
    assert _angle(_rot90_down(img), est.down) < 3.0
    assert _angle(_rot90_down(img), down) < 2.0


def test_segments_come_back_in_the_original_pixels():
    h, w = 3000, 4000  # 12 MP: found on a copy shrunk 7 times
    img = np.full((h, w, 3), 40, np.uint8)
    cv2.line(img, (500, 400), (3500, 2600), (255, 255, 255), 12, cv2.LINE_AA)
    cv2.rectangle(img, (0, 0), (w - 1, h - 1), (255, 255, 255), 30)  # a picture border: dropped
    segs = detect_segments(img)
    assert len(segs) >= 1
    long = segs[0]  # longest first; LSD finds the two sides of the thick line
    ends = sorted([tuple(long[:2]), tuple(long[2:])])
    assert np.allclose(ends[0], (500, 400), atol=25) and np.allclose(ends[1], (3500, 2600), atol=25)
    x, y = segs[:, 0::2], segs[:, 1::2]
    assert not np.any(np.all(x < 60, axis=1) | np.all(y < 60, axis=1))


def test_without_lsd_the_hough_fallback_gives_the_same_camera(monkeypatch):
    from cuboidcli.geometry import lines

    monkeypatch.setattr(lines, "_lsd", lambda grey: None)
    monkeypatch.setattr(lines, "_fast_line_detector", lambda grey: None)
    img, down = render_room(500.0, -15.0, 0.0, 30.0, seed=500)
    est = estimate_from_lines(img)
    assert est is not None
    assert _angle(est.down, down) < 2.0 and est.focal_px == pytest.approx(500.0, rel=0.05)


def test_fit_labels_follow_the_given_segments():
    img, _ = render_room(500.0, -15.0, 0.0, 30.0)
    segs = detect_segments(img)
    shuffled = segs[np.random.default_rng(0).permutation(len(segs))]
    degenerate = np.vstack([shuffled, [[5.0, 5.0, 5.0, 5.0], [np.nan, 0.0, 1.0, 1.0]]])
    fit = fit_manhattan(degenerate, (640, 480), fx=500.0)
    assert fit is not None and fit.labels.shape == (len(degenerate),)
    assert np.all(fit.labels[-2:] == -1)
    ref = fit_manhattan(segs, (640, 480), fx=500.0)
    order = np.argsort(np.random.default_rng(0).permutation(len(segs)))
    assert np.mean(fit.labels[:-2][order] >= 0) == pytest.approx(np.mean(ref.labels >= 0), abs=0.05)
    assert fit_manhattan(segs[:5], (640, 480)) is None


def test_a_12_mp_photo_costs_a_few_hundredths_of_a_second():
    img, _ = render_room(500.0, -15.0, 0.0, 30.0)
    big = cv2.resize(img, (4000, 3000), interpolation=cv2.INTER_LINEAR)
    estimate_from_lines(big)
    cpu = []
    for _ in range(3):
        t = time.process_time()
        estimate_from_lines(big)
        cpu.append(time.process_time() - t)
    # about 35 ms of CPU on one core (shrinking 10, LSD 15, vanishing points 10); the bound leaves room
    # for a slow machine, as the CPU time of a shared one varies too
    assert min(cpu) < 0.25, cpu


def _real_frames():
    """(name, rgb path, depth path, camera, depth scale) of the real RGB-D frames in ../shared/data."""
    from cuboidcli.camera import Camera

    data = SHARED_DATA
    if not (data / "nyu" / "cameras.json").is_file():
        return []
    out = []
    nyu = json.loads((data / "nyu" / "cameras.json").read_text())
    for name in ("basement_00000", "basement_00050", "basement_00100", "livingroom", "dining_crop"):
        rgb = next((data / "nyu").glob(f"{name}_rgb.*"))
        depth = data / "nyu" / (f"{name}_depth_filled.png" if name == "dining_crop" else f"{name}_depth.png")
        out.append((f"nyu/{name}", rgb, depth, Camera.from_dict(nyu[name]), 0.001))
    if (data / "tum" / "camera.json").is_file():
        tum = Camera.from_dict(json.loads((data / "tum" / "camera.json").read_text()))
        out.append(("tum", data / "tum" / "tum_rgb.png", data / "tum" / "tum_depth.png", tum, 2e-4))
    for rgb in sorted((data / "redwood" / "color").glob("*.jpg")):
        depth = data / "redwood" / "depth" / f"{rgb.stem}.png"
        out.append((f"redwood/{rgb.stem}", rgb, depth, Camera(525.0, 525.0, 319.5, 239.5, 640, 480), 0.001))
    return out


@pytest.fixture(scope="module")
def real_photos():
    """Per real frame: the lines' estimates from the photo alone (full frame, central 480x360 crop, turned
    by 90 degrees) and the down direction of its true depth."""
    from cuboidcli.geometry.gravity import estimate_gravity
    from cuboidcli.io.depth import read_depth, read_rgb

    frames = _real_frames()
    if not frames:
        pytest.skip("no real frames in ../shared/data")
    rows = []
    for name, rgb_path, depth_path, cam, scale in frames:
        rgb = read_rgb(rgb_path)
        g = estimate_gravity(cam.backproject(read_depth(depth_path, scale), 8))
        assert g is not None, name
        h, w = rgb.shape[:2]
        crop = np.ascontiguousarray(rgb[(h - 360) // 2 : (h + 360) // 2, (w - 480) // 2 : (w + 480) // 2])
        rows.append(
            {
                "name": name,
                "fx": cam.fx,
                "depth_down": g.down,
                "est": estimate_from_lines(rgb),
                "crop": estimate_from_lines(crop),
                "rot90_down": _rot90_down(rgb),
            }
        )
    return rows


def test_real_photos_down_agrees_with_the_depth(real_photos):
    for r in real_photos:
        est = r["est"]
        err = _angle(est.down, r["depth_down"])
        print(f"{r['name']}: down {err:.2f} deg from the depth's, confidence {est.down_confidence:.2f}")
        assert err < 5.0, r["name"]  # measured: 0.2-3.1 deg
        assert est.down_confidence > 0.5, r["name"]  # measured: 0.69-0.86
        assert _angle(est.down, r["rot90_down"]) < 3.0, r["name"]  # measured: at most 0.7 deg


def test_real_photos_focal_length(real_photos):
    def error(est, fx):
        """(relative fx error, confidence); inf without an estimate."""
        if est is None or est.focal_px is None:
            return math.inf, 0.0
        return abs(est.focal_px / fx - 1), est.focal_confidence

    ok_full, ok_crop = 0, 0
    for r in real_photos:
        (err, conf), (crop_err, crop_conf) = error(r["est"], r["fx"]), error(r["crop"], r["fx"])
        ok_full += err <= 0.10
        ok_crop += crop_err <= 0.10
        print(
            f"{r['name']}: fx {100 * err:.0f} % off (confidence {conf:.2f}), "
            f"480x360 crop {100 * crop_err:.0f} % off (confidence {crop_conf:.2f})"
        )
        # a focal length the fit takes is right (measured: 7 of 7 full frames, 1 of 1 crop; the most
        # confident wrong one, the living room's crop facing its wall, 31 % short at 0.15)
        assert conf < FOCAL_SURE or err <= 0.10, r["name"]
        assert crop_conf < FOCAL_SURE or crop_err <= 0.10, r["name"]
    print(f"within 10 %: full frames {ok_full}/{len(real_photos)}, crops {ok_crop}/{len(real_photos)}")
    assert ok_full >= len(real_photos) - 2  # measured: all but one (the living room, facing its wall)
    assert ok_crop >= len(real_photos) - 6  # measured: 7 of 11


def test_real_photos_fit_focal_length(real_photos):
    """The fx a fit without camera information takes (load.camera): the sure lines', else the default
    field of view unless the unsure lines rule it out. The default suits the full Kinect-like frames; a
    480x360 centre crop keeps fx, and the default (392 px) is 25 % short of it."""
    from cuboidcli.load import camera as cameras

    def fit_fx(est, w, h):
        camera = cameras.from_lines(est, w, h) or cameras.default_for(w, h, [], est)
        return camera.fx, camera.source

    full, crop, ruled = 0, 0, 0
    for r in real_photos:
        f_full, _ = (
            fit_fx(r["est"], 640, 480) if r["name"] != "nyu/dining_crop" else fit_fx(r["est"], 560, 425)
        )
        f_crop, source = fit_fx(r["crop"], 480, 360)
        full += abs(f_full / r["fx"] - 1) <= 0.10
        crop += abs(f_crop / r["fx"] - 1) <= 0.10
        ruled += "rule out" in source
        print(f"{r['name']}: the fit's fx {f_full:.0f} px, its crop's {f_crop:.0f} px ({source})")
    assert full == len(real_photos)  # measured: 11 of 11
    assert crop >= len(real_photos) - 5  # measured: 7 of 11 (the default alone: 1)
    assert ruled >= 5  # measured: 7 crops whose default the lines rule out, 6 of them right

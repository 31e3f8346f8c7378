"""Photos: upright pixels after the EXIF orientation, intrinsics from EXIF focal lengths (for the upright
image), corrupt tags skipped with a note, unreadable files one-line InputErrors, the default camera."""

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest
from PIL import ExifTags, Image
from PIL.TiffImagePlugin import IFDRational

from cuboidcli.camera import Camera
from cuboidcli.io.depth import InputError
from cuboidcli.io.photo import DEFAULT_FOV_DEG, default_camera, exif_intrinsics, read_photo

ORIENTATION = 274
F35, FOCAL, XRES, YRES, UNIT, PIXEL_X, PIXEL_Y = 41989, 37386, 41486, 41487, 41488, 40962, 40963

#: EXIF orientation -> how the stored pixels (rows, columns, channels) look upright, written in numpy
#: from the EXIF definitions ("row 0 is the visual right-hand side, column 0 the top" for 6, ...).
UPRIGHT = {
    1: lambda s: s,
    2: lambda s: s[:, ::-1],
    3: lambda s: s[::-1, ::-1],
    4: lambda s: s[::-1],
    5: lambda s: s.transpose(1, 0, 2),
    6: lambda s: np.rot90(s, -1),
    7: lambda s: s[::-1, ::-1].transpose(1, 0, 2),
    8: lambda s: np.rot90(s, 1),
}


def pattern(h: int = 48, w: int = 64) -> np.ndarray:
    """8x8 blocks of distinct colours (aligned with JPEG blocks, so they survive compression)."""
    rng = np.random.default_rng(7)
    blocks = rng.integers(0, 256, (h // 8, w // 8, 3), dtype=np.uint8)
    return np.repeat(np.repeat(blocks, 8, axis=0), 8, axis=1)


def write_jpeg(path, rgb: np.ndarray, orientation: int | None = None, **exif_tags):
    exif = Image.Exif()
    if orientation is not None:
        exif[ORIENTATION] = orientation
    ifd = exif.get_ifd(ExifTags.IFD.Exif)
    for tag, value in exif_tags.items():
        ifd[int(tag.lstrip("t"))] = value
    Image.fromarray(rgb).save(path, quality=95, subsampling=0, exif=exif)
    return path


def tags(**named) -> dict:
    return {int(k.lstrip("t")): v for k, v in named.items()}


def close(a: np.ndarray, b: np.ndarray) -> bool:
    return a.shape == b.shape and float(np.abs(a.astype(float) - b.astype(float)).mean()) < 4.0


@pytest.mark.parametrize("orientation", range(1, 9))
def test_orientation_gives_upright_pixels_and_intrinsics(tmp_path, orientation):
    stored = pattern()
    path = write_jpeg(tmp_path / "p.jpg", stored, orientation, t41989=26)
    photo = read_photo(path)
    upright = UPRIGHT[orientation](stored)
    assert photo.orientation == orientation
    assert photo.rgb.dtype == np.uint8 and photo.rgb.flags.writeable
    assert close(photo.rgb, upright)
    others = [o for o in UPRIGHT if o != orientation]
    assert not any(close(photo.rgb, UPRIGHT[o](stored)) for o in others)  # the pattern tells them apart
    h, w = upright.shape[:2]
    cam = photo.exif_camera
    assert (cam.width, cam.height) == (w, h) == ((48, 64) if orientation >= 5 else (64, 48))
    assert (cam.cx, cam.cy) == ((w - 1) / 2, (h - 1) / 2)
    assert cam.fx == cam.fy == pytest.approx(26 / 36 * 64)
    assert photo.notes == []


def test_35mm_equivalent_on_a_full_size_phone_photo(tmp_path):
    path = write_jpeg(tmp_path / "phone.jpg", np.full((3024, 4032, 3), 128, np.uint8), t41989=26)
    cam = read_photo(path).exif_camera
    assert cam.fx == pytest.approx(2912, rel=0.02) and cam.fy == cam.fx
    assert (cam.cx, cam.cy, cam.width, cam.height) == (2015.5, 1511.5, 4032, 3024)
    assert cam.source == "exif: FocalLengthIn35mmFilm 26 mm"


@pytest.mark.parametrize("unit, mm_per_unit", [(2, 25.4), (3, 10.0), (4, 1.0), (5, 0.001), (None, 25.4)])
def test_focal_length_with_the_sensor_resolution(tmp_path, unit, mm_per_unit):
    """35 mm lens, 250 px/mm sensor (a 6000 x 4000 px, 24 x 16 mm sensor) on a 60 x 40 copy of its image:
    fx = 35 * 250 * 60 / 6000 = 87.5 px; fy from the Y resolution (here 240 px/mm: 84 px)."""
    unit_tag = {} if unit is None else {"t41488": unit}
    path = write_jpeg(
        tmp_path / "dslr.jpg",
        pattern(40, 64)[:, :60],
        t37386=IFDRational(35, 1),
        t41486=250 * mm_per_unit,
        t41487=240 * mm_per_unit,
        t40962=6000,
        t40963=4000,
        **unit_tag,
    )
    photo = read_photo(path)
    assert photo.exif_camera.fx == pytest.approx(87.5)
    assert photo.exif_camera.fy == pytest.approx(84.0)
    assert photo.exif_camera.source.startswith("exif: FocalLength 35 mm")
    assert photo.notes == []


def test_sensor_resolution_follows_the_orientation():
    """Orientation 6 swaps the axes: the sensor's X resolution gives the upright image's fy."""
    t = tags(t37386=4.0, t41486=15.0, t41487=18.0, t41488=4)
    assert exif_intrinsics(t, 64, 48, 1) == exif_intrinsics(t, 64, 48) != exif_intrinsics(t, 64, 48, 6)
    cam = exif_intrinsics(t, 64, 48, 1)
    assert (cam.fx, cam.fy, cam.width, cam.height) == (60.0, 72.0, 64, 48)
    cam = exif_intrinsics(t, 64, 48, 6)
    assert (cam.fx, cam.fy, cam.width, cam.height, cam.cx, cam.cy) == (72.0, 60.0, 48, 64, 23.5, 31.5)


def test_35mm_equivalent_comes_before_the_focal_length():
    t = tags(t41989=26, t37386=4.0, t41486=15.0, t41488=4)
    assert exif_intrinsics(t, 64, 48).fx == pytest.approx(26 / 36 * 64)


def test_no_exif_means_no_camera(tmp_path):
    path = tmp_path / "plain.jpg"
    Image.fromarray(pattern()).save(path, quality=95, subsampling=0)
    photo = read_photo(path)
    assert photo.exif_camera is None and photo.orientation == 1 and photo.notes == []
    assert close(photo.rgb, pattern())
    # Focal length without the sensor size is not enough, and says nothing.
    assert read_photo(write_jpeg(tmp_path / "f.jpg", pattern(), t37386=4.2)).exif_camera is None
    assert read_photo(write_jpeg(tmp_path / "f.jpg", pattern(), t37386=4.2)).notes == []


@pytest.mark.parametrize(
    "bad, words",
    [
        ({"t41989": 0}, "FocalLengthIn35mmFilm = 0 is not a positive number"),
        ({"t41989": 1000}, "FocalLengthIn35mmFilm = 1000 mm implies a 2.1 degree field of view"),
        ({"t41989": 2}, "field of view"),
        ({"t41989": "26 mm"}, "FocalLengthIn35mmFilm = '26 mm' is not a number"),
        ({"t37386": IFDRational(1, 0), "t41486": 15.0}, "FocalLength is a fraction with a zero denominator"),
        ({"t37386": 4.0, "t41486": "abc"}, "FocalPlaneXResolution = 'abc' is not a number"),
        ({"t37386": 4.0, "t41486": -15.0}, "FocalPlaneXResolution = -15 is not a positive number"),
        ({"t37386": 4.0, "t41486": 15.0, "t41488": 1}, "FocalPlaneResolutionUnit = 1 is not 2-5"),
        ({"t37386": 4.0, "t41486": 15.0, "t41487": 60.0, "t41488": 4}, "pixels 0.25 times as wide"),
        ({"t37386": 400.0, "t41486": 15.0, "t41488": 4}, "implies a 0.6 degree field of view"),
    ],
)
def test_corrupt_tags_are_ignored_with_a_note(tmp_path, bad, words):
    photo = read_photo(write_jpeg(tmp_path / "bad.jpg", pattern(), **bad))
    assert photo.exif_camera is None
    assert len(photo.notes) == 1 and words in photo.notes[0] and "\n" not in photo.notes[0]


def test_a_corrupt_35mm_tag_falls_through_to_the_focal_length(tmp_path):
    photo = read_photo(write_jpeg(tmp_path / "b.jpg", pattern(), t41989=0, t37386=4.0, t41486=15.0, t41488=4))
    assert photo.exif_camera.fx == 60.0 and len(photo.notes) == 1


def test_a_bad_orientation_is_ignored_with_a_note(tmp_path):
    photo = read_photo(write_jpeg(tmp_path / "o.jpg", pattern(), 9))
    assert photo.orientation == 1 and close(photo.rgb, pattern())
    assert photo.notes == ["EXIF Orientation = 9 is not 1-8; image used as stored"]


def test_image_modes(tmp_path):
    import cv2

    grey = pattern()[..., 0]
    Image.fromarray(grey).save(tmp_path / "grey.jpg", quality=95)
    rgb = read_photo(tmp_path / "grey.jpg").rgb
    assert rgb.shape == (48, 64, 3) and close(rgb, np.repeat(grey[..., None], 3, axis=2))
    rgba = np.dstack([pattern(), np.full((48, 64), 7, np.uint8)])
    Image.fromarray(rgba).save(tmp_path / "rgba.png")
    assert np.array_equal(read_photo(tmp_path / "rgba.png").rgb, pattern())
    cv2.imwrite(str(tmp_path / "c16.png"), pattern()[..., ::-1].astype(np.uint16) * 257)
    assert np.array_equal(read_photo(tmp_path / "c16.png").rgb, pattern())


@pytest.mark.parametrize(
    "name, content, words",
    [
        ("text.jpg", b"not a photo\n", "^cannot decode image .*text.jpg \\(corrupt or not an image file\\)"),
        ("cut.jpg", "truncated", "^cannot decode image .*cut.jpg \\(.*truncated"),
        (
            "depth.png",
            "depth",
            r"^\S*depth.png is a single-channel I;16 image, not an 8-bit colour photo; if it is a depth map, "
            r"pass it with --depth: cuboids fit --depth \S*depth.png$",
        ),
        ("missing.jpg", None, "^image file not found: .*missing.jpg$"),
    ],
)
def test_unreadable_files_are_one_line_input_errors(tmp_path, name, content, words):
    import cv2

    path = tmp_path / name
    if content == "truncated":
        Image.fromarray(np.random.default_rng(0).integers(0, 256, (240, 320, 3), np.uint8)).save(path)
        path.write_bytes(path.read_bytes()[: path.stat().st_size // 2])
    elif content == "depth":
        cv2.imwrite(str(path), np.full((48, 64), 1500, np.uint16))
    elif content is not None:
        path.write_bytes(content)
    with pytest.raises(InputError, match=words) as info:
        read_photo(path)
    assert "\n" not in str(info.value)


@pytest.mark.parametrize(
    "w, h, fov", [(640, 480, DEFAULT_FOV_DEG), (480, 640, DEFAULT_FOV_DEG), (4032, 3024, 75)]
)
def test_default_camera_has_the_stated_field_of_view(w, h, fov):
    intr = default_camera(w, h, fov)
    long_fov = Camera(intr.fx, intr.fy, intr.cx, intr.cy, w, h).fov_deg()[0 if w >= h else 1]
    assert long_fov == pytest.approx(fov)
    assert intr.fx == intr.fy and (intr.cx, intr.cy) == ((w - 1) / 2, (h - 1) / 2)
    assert (intr.width, intr.height) == (w, h) and intr.source.startswith("default:")
    assert DEFAULT_FOV_DEG == 63  # README, "From a photo"
    with pytest.raises(InputError):
        default_camera(w, h, 180)


def test_pillow_is_imported_only_when_a_photo_is_read():
    code = "import sys, cuboidcli.io.photo; assert 'PIL' not in sys.modules, 'PIL imported'"
    root = Path(__file__).resolve().parents[2]
    proc = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, cwd=root, timeout=60)
    assert proc.returncode == 0, proc.stderr[-2000:]


def test_fov_range_boundaries():
    """f35 = 18 / tan(75 deg) = 4.82 mm is 150 degrees: 5 mm is kept, 4.5 mm is not."""
    assert exif_intrinsics(tags(t41989=5), 64, 48) is not None
    assert exif_intrinsics(tags(t41989=4.5), 64, 48) is None
    assert math.isclose(exif_intrinsics(tags(t41989=5), 64, 48).fx, 5 / 36 * 64)


def test_partial_sensor_tags():
    """Only PixelXDimension: the width alone scales; no Y resolution: square pixels; one-value tuples."""
    t = tags(t37386=(4.0,), t41486=15.0, t41488=4, t40962=128)
    cam = exif_intrinsics(t, 64, 48)
    assert (cam.fx, cam.fy) == (30.0, 30.0)

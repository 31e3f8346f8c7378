"""`cuboids fit` on small inputs, and one test per class of bad input (message and exit code)."""

import json
import os
from pathlib import Path

import cv2
import numpy as np
import pytest
from typer.testing import CliRunner

from cuboidcli.cli.main import app

ROOT = Path(__file__).resolve().parents[2]

runner = CliRunner()
FAST = ["--hypotheses", "256", "--max-cuboids", "3"]


def run(*args):
    return runner.invoke(app, [str(a) for a in args])


def test_fit_writes_schema_json(tmp_path, room_png):
    out = tmp_path / "out" / "room.json"
    r = run("fit", "--depth", room_png, "--camera", "nyu", "-o", out, *FAST, "--seed", "3")
    assert r.exit_code == 0, r.output
    d = json.loads(out.read_text())
    assert d["schema"] == "cuboids/1" and d["frame"] == "opencv"
    assert d["camera"] == {
        "fx": 518.8579,
        "fy": 519.4696,
        "cx": 325.5824,
        "cy": 253.7362,
        "width": 640,
        "height": 480,
    }
    assert 1 <= len(d["cuboids"]) <= 3
    c = d["cuboids"][0]
    R = np.array(c["rotation"])
    np.testing.assert_allclose(R @ R.T, np.eye(3), atol=1e-5)
    assert c["id"] == 0 and len(c["quat_wxyz"]) == 4 and c["inlier_gain"] > d["settings"]["theta_used"]
    assert d["settings"]["seed"] == 3 and d["settings"]["hypotheses"] == 256
    # what the seed's cuboids depend on beyond the options: the generator and the backend used
    assert (d["settings"]["random_generator"], d["settings"]["backend_used"]) == ("numpy", "numba")
    assert d["timing_s"]["total"] > 0 and d["input"]["depth_scale"] == 0.001
    assert "cuboids" in r.output and "wrote" in r.output
    # deterministic with --seed
    out2 = tmp_path / "again.json"
    run("fit", "--depth", room_png, "--camera", "nyu", "-o", out2, *FAST, "--seed", "3")
    assert json.loads(out2.read_text())["cuboids"] == d["cuboids"]


def test_fit_folder_and_intrinsics_forms(tmp_path, room_png):
    folder = tmp_path / "frames"
    folder.mkdir()
    for name in ("a", "b"):
        (folder / f"{name}.png").write_bytes(room_png.read_bytes())
    r = run(
        "fit",
        "--depth",
        folder,
        "-K",
        "518.8579,519.4696,325.5824,253.7362",
        "-o",
        tmp_path / "res",
        *FAST,
        "-q",
    )
    assert r.exit_code == 0, r.output
    assert sorted(p.name for p in (tmp_path / "res").iterdir()) == ["a_cuboids.json", "b_cuboids.json"]
    cam = tmp_path / "cam.json"
    cam.write_text(json.dumps({"fx": 500.0, "fy": 500.0, "cx": 320.0, "cy": 240.0}))
    r = run("fit", "--depth", room_png, "-K", cam, "-o", tmp_path / "k.json", *FAST, "-q")
    assert r.exit_code == 0, r.output
    assert json.loads((tmp_path / "k.json").read_text())["camera"]["fx"] == 500.0


@pytest.mark.parametrize(
    "kind", ["missing", "corrupt", "zeros", "wrong_unit", "mm_focal", "rgb_size", "eight_bit"]
)
def test_bad_inputs_give_one_line_errors(tmp_path, room_png, kind):
    args = ["fit", "--depth", room_png, "--camera", "nyu", "-o", tmp_path / "x.json", *FAST]
    if kind == "missing":
        args[2] = tmp_path / "nope.png"
        expect = "depth map not found"
    elif kind == "corrupt":
        bad = tmp_path / "bad.png"
        bad.write_bytes(b"\x89PNG\r\n\x1a\n garbage")
        args[2] = bad
        expect = "cannot decode"
    elif kind == "zeros":
        z = tmp_path / "z.png"
        cv2.imwrite(str(z), np.zeros((48, 64), np.uint16))
        args[2] = z
        expect = "no valid pixels"
    elif kind == "wrong_unit":
        mm = tmp_path / "mm.npy"  # millimetres saved where metres are expected
        np.save(mm, np.full((48, 64), 2500.0, np.float32))
        args[2] = mm
        expect = "unit looks wrong"
    elif kind == "mm_focal":
        args[3:5] = ["-K", "3.5,3.5,320,240"]
        expect = "millimetres"
    elif kind == "rgb_size":
        img = tmp_path / "small.png"
        cv2.imwrite(str(img), np.zeros((10, 10, 3), np.uint8))
        args.insert(1, img)
        expect = "RGB image is 10x10"
    else:
        e8 = tmp_path / "e8.png"
        cv2.imwrite(str(e8), np.full((48, 64), 100, np.uint8))
        args[2] = e8
        expect = "8-bit"
    r = run(*args)
    assert r.exit_code == 2, r.output
    assert expect in r.output
    assert "Traceback" not in r.output
    assert not (tmp_path / "x.json").exists()


def test_option_errors(tmp_path, room_png):
    r = run("fit", "--depth", room_png, "--hypotheses", "0")
    assert r.exit_code == 2 and "--hypotheses" in r.output
    r = run("fit", "--depth", room_png, "--device", "cuda")
    if "error" in r.output:
        assert r.exit_code == 2 and "CUDA" in r.output
    r = run("fit")
    assert r.exit_code == 2 and "--depth" in r.output
    r = run("fit", "--depth", room_png, "--solver", "onnx")
    assert r.exit_code == 2 and "--onnx" in r.output
    out = tmp_path / "ignored.json"  # an ONNX file for another solver: refused, not dropped without a word
    r = run("fit", "--depth", room_png, "--onnx", tmp_path / "s.onnx", "-o", out)
    assert r.exit_code == 2 and "--onnx applies to --solver onnx" in r.output and not out.exists()
    assert len(r.output.strip().splitlines()) == 1


def test_depth_formats_npy_npz_exr(tmp_path, room_depth):
    from cuboidcli.io.depth import read_depth

    depth = room_depth[0]
    np.save(tmp_path / "d.npy", depth)
    np.savez(tmp_path / "d.npz", depth=depth)
    for name in ("d.npy", "d.npz"):
        np.testing.assert_array_equal(read_depth(tmp_path / name), depth)
    OpenEXR = pytest.importorskip("OpenEXR")
    with OpenEXR.File({"type": OpenEXR.scanlineimage}, {"Z": depth.astype(np.float32)}) as f:
        f.write(str(tmp_path / "d.exr"))
    np.testing.assert_array_equal(read_depth(tmp_path / "d.exr"), depth)
    nan = depth.copy()
    nan[:10] = np.nan
    nan[10:20] = np.inf
    np.save(tmp_path / "nan.npy", nan)
    got = read_depth(tmp_path / "nan.npy")
    assert (got[:20] == 0).all() and np.isfinite(got).all()


#: Exactly one cuboid, quickly: whatever a tiny random depth network predicts.
ONE_CUBOID = ["--hypotheses", "64", "--theta", "-1e9", "--max-cuboids", "1"]


@pytest.fixture
def tiny_depth_weights(tmp_path):
    """A tiny random built-in depth network, saved as a checkpoint."""
    import torch

    from cuboidcli.nets.checkpoint import checkpoint_dict
    from cuboidcli.nets.depth import DepthNet, DepthNetConfig

    torch.manual_seed(0)
    weights = tmp_path / "depth.pt"
    torch.save(checkpoint_dict(DepthNet(DepthNetConfig(channels=(4, 8, 8, 8, 8)))), weights)
    return weights


def test_rgb_only_uses_the_depth_estimator(tmp_path, tiny_depth_weights):
    """Without --depth the built-in depth network (a tiny random one here) provides the depth, and says so."""
    rgb = (np.random.default_rng(0).uniform(0, 255, (120, 160, 3))).astype(np.uint8)
    img = tmp_path / "rgb.png"
    cv2.imwrite(str(img), rgb)
    out = tmp_path / "rgb.json"
    r = run("fit", img, "-K", "130,130,80,60", "--depth-model", tiny_depth_weights, "-o", out, *ONE_CUBOID)
    assert r.exit_code == 0, r.output
    assert "depth estimated from RGB" in r.output
    d = json.loads(out.read_text())
    assert d["input"]["depth"] is None and "built-in network" in d["input"]["depth_source"]
    assert len(d["cuboids"]) == 1
    # The estimation is a stage of the frame's fitting time, listed first and counted in the total.
    t = d["timing_s"]
    assert next(iter(t)) == "depth" and t["depth"] > 0
    stages = sum(v for k, v in t.items() if k not in ("total", "assign"))
    assert t["total"] >= stages - 1e-5 and t["total"] >= t["depth"] + t["solve"] + t["score"] - 1e-5
    r = run("fit", img, "--depth-model", tmp_path / "missing.pt", "-o", out)
    assert r.exit_code == 2 and "not found" in r.output


def test_rgb_folder_fits_every_photo_with_one_estimator(tmp_path, monkeypatch, tiny_depth_weights):
    """IMAGE may be a folder: every colour image is fitted from estimated depth, depth PNGs next to the photos
    are left out with one note, per-frame intrinsics are found by the frame name without "_rgb", and the
    depth network is loaded once for the whole folder."""
    from cuboidcli import factories
    from cuboidcli.depth import estimator as estimator_mod

    folder = tmp_path / "frames"
    folder.mkdir()
    rng = np.random.default_rng(0)
    cams = {}
    for name in ("a", "b"):
        cv2.imwrite(str(folder / f"{name}_rgb.jpg"), rng.uniform(0, 255, (120, 160, 3)).astype(np.uint8))
        cv2.imwrite(str(folder / f"{name}_depth.png"), np.full((120, 160), 2000, np.uint16))
        cams[name] = {"fx": 130.0, "fy": 130.0, "cx": 80.0, "cy": 60.0}
    (folder / "cameras.json").write_text(json.dumps(cams))
    loads = []
    real = estimator_mod.BuiltinDepthEstimator.__init__
    monkeypatch.setattr(
        estimator_mod.BuiltinDepthEstimator,
        "__init__",
        lambda self, *a, **k: loads.append(1) or real(self, *a, **k),
    )
    factories.depth_estimator.cache_clear()
    out = tmp_path / "out"
    r = run("fit", folder, "--depth-model", tiny_depth_weights, "-o", out, *ONE_CUBOID)
    assert r.exit_code == 0, r.output
    assert "left out 2 files" in r.output and r.output.count("depth estimated from RGB") == 1
    assert sorted(p.name for p in out.iterdir()) == ["a_rgb_cuboids.json", "b_rgb_cuboids.json"]
    for name in ("a", "b"):
        d = json.loads((out / f"{name}_rgb_cuboids.json").read_text())
        assert d["input"]["depth"] is None and d["timing_s"]["depth"] > 0 and len(d["cuboids"]) == 1
        assert d["camera"]["fx"] == 130.0
    assert len(loads) == 1
    # A folder of images with --depth, or with one partial depth map, is refused in one line.
    r = run("fit", folder, "--depth", folder / "a_depth.png")
    assert r.exit_code == 2 and "IMAGE is a folder" in r.output
    r = run("fit", folder / "a_rgb.jpg", "--depth", folder)  # one image for a folder of depth maps
    assert r.exit_code == 2 and "leave IMAGE out" in r.output
    r = run("fit", folder, "--partial-depth", folder / "a_depth.png")
    assert r.exit_code == 2 and "--partial-depth belongs to one image" in r.output
    empty = tmp_path / "empty"
    empty.mkdir()
    r = run("fit", empty)
    assert r.exit_code == 2 and "no colour images" in r.output


def test_demo_writes_every_output(tmp_path):
    r = run("demo", "-o", tmp_path / "demo")
    assert r.exit_code == 0, r.output
    names = sorted(p.name for p in (tmp_path / "demo").iterdir())
    assert names == sorted(
        [
            "sample_cuboids.json",
            "sample_cuboids.glb",
            "sample_cuboids_points.ply",
            "sample_cuboids_cuboids.ply",
            "sample_cuboids_overlay.png",
            "sample_cuboids_labels.png",
            "sample_cuboids_labels_color.png",
            "sample_cuboids_panel.png",
        ]
    )
    d = json.loads((tmp_path / "demo" / "sample_cuboids.json").read_text())
    assert len(d["cuboids"]) >= 2  # at least the two walls of the sample room


def test_a_closed_output_pipe_is_not_an_internal_error():
    """``cuboids fit --help | head``: the reader takes the first lines and closes the pipe while the help
    is still being written."""
    import subprocess
    import sys

    proc = subprocess.Popen(
        [sys.executable, "-c", "from cuboidcli.cli.main import run; run()", "fit", "--help"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
    )
    proc.stdout.read(2000)
    proc.stdout.close()
    _, err = proc.communicate(timeout=120)
    assert proc.returncode in (0, 1)  # 0 when the whole help was written before the pipe closed
    assert b"internal error" not in err and b"Traceback" not in err, err.decode()


def test_fit_never_loads_the_training_package(tmp_path):
    """``cuboids fit`` in a fresh process runs without importing ``cuboidcli.learn``: the train commands,
    whose options come from the training configs, are built only when ``cuboids train`` is used."""
    sample = "cuboidcli/data/sample"
    fit = ["fit", "--depth", f"{sample}/sample_depth.png", "-K", f"{sample}/camera.json", "--hypotheses=64"]
    assert _modules_loaded_by([*fit, "-o", str(tmp_path / "r.json")], ("cuboidcli.learn",)) == []
    assert "cuboidcli.learn.seed_train" in _modules_loaded_by(
        ["train", "seed", "--help"], ("cuboidcli.learn",)
    )


def test_a_default_frame_fit_never_imports_torch(tmp_path):
    """A depth map fitted with the default parts on the CPU (the sequential sampler, the numerical solver,
    the numba kernels) runs on numpy and numba alone, in the command and in the Python API: torch takes
    about a second to import, longer than the fit."""
    sample = "cuboidcli/data/sample"
    out = tmp_path / "r.json"
    fit = ["fit", "--depth", f"{sample}/sample_depth.png", "-K", f"{sample}/camera.json", "-o", str(out)]
    assert _modules_loaded_by([*fit, "--hypotheses=256"], ("torch",)) == []
    assert json.loads(out.read_text())["cuboids"]
    assert _modules_loaded_by([*fit, "--hypotheses=256", "--overlay", "--glb"], ("torch",)) == []
    api = (
        "import sys, cuboidcli as cb\n"
        f"d = {str(ROOT / sample)!r}\n"
        "r = cb.Fitter(hypotheses=256).fit(d + '/sample_depth.png', intrinsics=d + '/camera.json')\n"
        "assert r.cuboids\n"
        "print(sorted(m for m in sys.modules if m.startswith('torch')))\n"
    )
    assert _python_prints(api) == "[]"


def _python_prints(code: str) -> str:
    """The last line ``python -c CODE`` prints in a fresh process."""
    import subprocess
    import sys

    out = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True, timeout=300, cwd=ROOT)
    assert out.returncode == 0, out.stderr
    return out.stdout.strip().splitlines()[-1]


def _modules_loaded_by(args: list[str], prefixes: tuple[str, ...]) -> list[str]:
    """The modules starting with one of ``prefixes`` that ``cuboids ARGS`` imports in a fresh process."""
    import subprocess
    import sys

    code = (
        "import json, sys\n"
        "from cuboidcli.cli.main import app\n"
        "try:\n"
        "    app(sys.argv[1:])\n"
        "except SystemExit as e:\n"
        "    assert not e.code, e.code\n"
        f"print(json.dumps(sorted(m for m in sys.modules if m.startswith({prefixes!r}))))\n"
    )
    out = subprocess.run(
        [sys.executable, "-c", code, *args], capture_output=True, text=True, timeout=300, cwd=ROOT
    )
    assert out.returncode == 0, out.stderr
    return eval(out.stdout.strip().splitlines()[-1])


def _phone_jpeg(path, rgb_upright: np.ndarray, orientation: int, f35: float | None) -> None:
    """A JPEG as a phone writes it: the pixels stored turned (orientation 6: the upright image is the stored
    one turned 90 degrees clockwise), the orientation and the 35 mm equivalent focal length as EXIF tags."""
    from PIL import Image

    stored = np.rot90(rgb_upright, k=1) if orientation == 6 else rgb_upright  # undo a clockwise turn
    exif = Image.Exif()
    exif[0x0112] = orientation
    if f35 is not None:
        exif.get_ifd(0x8769)[41989] = f35
    Image.fromarray(np.ascontiguousarray(stored)).save(path, exif=exif, quality=95)


def test_a_phone_photo_is_fitted_upright_with_the_camera_of_its_exif(tmp_path, tiny_depth_weights):
    """A portrait photo stored landscape with orientation 6 and a 26 mm equivalent lens: the fit sees the
    upright 120x160 image, fx = 26 / 36 x 160 px, principal point at the centre, and the JSON says so."""
    upright = np.zeros((160, 120, 3), np.uint8)
    upright[:40] = (250, 30, 30)  # a red top, so that "upright" is visible in the overlay
    upright[40:] = (40, 120, 200)
    photo = tmp_path / "phone.jpg"
    _phone_jpeg(photo, upright, 6, 26)
    out = tmp_path / "phone.json"
    free = ["--align", "free"]  # a random network's depth has no floor to find gravity on
    r = run("fit", photo, "--depth-model", tiny_depth_weights, "-o", out, "--overlay", *ONE_CUBOID, *free)
    assert r.exit_code == 0, r.output
    d = json.loads(out.read_text())
    cam = d["camera"]
    assert (cam["width"], cam["height"]) == (120, 160)
    assert cam["fx"] == pytest.approx(26 / 36 * 160) and cam["fy"] == cam["fx"]
    assert (cam["cx"], cam["cy"]) == (59.5, 79.5)
    assert d["input"]["intrinsics_source"] == "exif: FocalLengthIn35mmFilm 26 mm"
    overlay = cv2.imread(str(tmp_path / "phone_overlay.png"))
    assert overlay.shape[:2] == (160, 120)
    assert "warning" not in r.output
    # Without any camera information: the default field of view, one warning, a fitted result.
    bare = tmp_path / "bare.jpg"
    _phone_jpeg(bare, upright, 1, None)
    r = run(
        "fit", bare, "--depth-model", tiny_depth_weights, "-o", tmp_path / "bare.json", *ONE_CUBOID, *free
    )
    assert r.exit_code == 0, r.output
    assert r.output.count("warning:") == 1 and "63 degree field of view" in " ".join(r.output.split())
    d = json.loads((tmp_path / "bare.json").read_text())
    assert d["input"]["intrinsics_source"].startswith("default: 63 degree")
    assert d["camera"]["cx"] == 59.5 and len(d["cuboids"]) == 1


def test_fit_writes_the_html_page_beside_the_json(tmp_path, room_png):
    pytest.importorskip("plotly")
    out = tmp_path / "room.json"
    r = run("fit", "--depth", room_png, "--camera", "nyu", "-o", out, "--html", *FAST)
    assert r.exit_code == 0, r.output
    page = (tmp_path / "room.html").read_text()
    assert "room.html" in "".join(r.output.split())  # listed among the files written
    assert "<script src=" not in page and "Mesh3d".lower() in page.lower()


def test_fit_writes_simulator_scenes_beside_the_json(tmp_path, room_png):
    mujoco = pytest.importorskip("mujoco")
    out = tmp_path / "room.json"
    r = run("fit", "--depth", room_png, "--camera", "nyu", "-o", out, "--mjcf", "--urdf", "--usd", *FAST)
    assert r.exit_code == 0, r.output
    names = [c["kind"] + f"_{c['id']:02d}" for c in json.loads(out.read_text())["cuboids"]]
    model = mujoco.MjModel.from_xml_path(str(tmp_path / "room_mjcf.xml"))
    assert [mujoco.mj_id2name(model, mujoco.mjtObj.mjOBJ_GEOM, g) for g in range(model.ngeom)] == names
    assert mujoco.MjModel.from_xml_path(str(tmp_path / "room.urdf")).ngeom == len(names)
    assert "no gravity" not in r.output  # the room's gravity was estimated: a levelled scene
    from pxr import Usd, UsdGeom

    stage = Usd.Stage.Open(str(tmp_path / "room.usda"))
    assert [p.GetParent().GetName() for p in stage.Traverse() if p.IsA(UsdGeom.Cube)] == names


def test_rerun_recordings_of_a_frame_and_of_a_folder(tmp_path, room_png, rerun_cli):
    """--rrd: <out>.rrd for one frame; for a folder one cuboids.rrd with every frame on the `frame`
    timeline, which rerun's own `rrd verify` accepts. --rerun without a viewer: one line, exit 2."""
    import shutil
    import subprocess

    out = tmp_path / "one.json"
    r = run("fit", "--depth", room_png, "--camera", "nyu", "-o", out, "--rrd", *FAST)
    assert r.exit_code == 0, r.output
    assert subprocess.run([rerun_cli, "rrd", "verify", str(tmp_path / "one.rrd")]).returncode == 0
    folder = tmp_path / "frames"
    folder.mkdir()
    for name in ("a", "b"):
        shutil.copy(room_png, folder / f"{name}_depth.png")
    r = run("fit", "--depth", folder, "--camera", "nyu", "-o", tmp_path / "res", "--rrd", *FAST)
    assert r.exit_code == 0, r.output
    rec = tmp_path / "res" / "cuboids.rrd"
    assert subprocess.run([rerun_cli, "rrd", "verify", str(rec)]).returncode == 0
    printed = subprocess.run([rerun_cli, "rrd", "print", "-vvv", str(rec)], capture_output=True, text=True)
    box_rows = [line for line in printed.stdout.splitlines() if "Boxes3D" not in line and "_00," in line]
    assert sorted(int(line.split("┆")[1].strip()) for line in box_rows) == [0, 1]
    assert not list((tmp_path / "res").glob("*_cuboids.rrd"))  # one recording, not one per frame
    import socket

    with socket.socket() as probe:
        if probe.connect_ex(("127.0.0.1", 9876)) == 0:
            return  # a viewer is running here: the refusal cannot be seen
    r = run("fit", "--depth", room_png, "--camera", "nyu", "-o", tmp_path / "s.json", "--rerun", *FAST)
    assert r.exit_code == 2 and "no rerun viewer answers" in r.output and not (tmp_path / "s.json").exists()


def test_rerun_streams_a_fit_to_a_running_viewer(tmp_path, room_png, rerun_cli):
    """--rerun sends the frame to a rerun server on this machine (`rerun --port 9876 --save`, headless),
    which records the boxes under their scene names."""
    import signal
    import socket
    import subprocess
    import time

    with socket.socket() as probe:
        if probe.connect_ex(("127.0.0.1", 9876)) == 0:
            pytest.skip("port 9876 is in use")
    saved = tmp_path / "live.rrd"
    server = subprocess.Popen(
        [rerun_cli, "--port", "9876", "--save", str(saved)],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
        start_new_session=True,  # the launcher may start the viewer as a child: signal them together
    )
    try:
        for _ in range(100):  # until it listens (at most 10 s)
            with socket.socket() as probe:
                if probe.connect_ex(("127.0.0.1", 9876)) == 0:
                    break
            time.sleep(0.1)
        out = tmp_path / "room.json"
        r = run("fit", "--depth", room_png, "--camera", "nyu", "-o", out, "--rerun", *FAST)
        assert r.exit_code == 0, r.output
    finally:
        time.sleep(1.0)
        os.killpg(server.pid, signal.SIGINT)  # it finishes the file and exits
        try:
            server.wait(timeout=20)
        except subprocess.TimeoutExpired:
            os.killpg(server.pid, signal.SIGKILL)
            server.wait()
    names = [c["kind"] + f"_{c['id']:02d}" for c in json.loads(out.read_text())["cuboids"]]
    printed = subprocess.run([rerun_cli, "rrd", "print", "-vvv", str(saved)], capture_output=True, text=True)
    assert all(name in printed.stdout for name in names)


def test_the_old_preset_spelling_still_works_and_warns(tmp_path, room_png):
    """--camera is the camera preset; --preset, its old spelling, still works (hidden from --help) with a
    one-line warning and writes the same JSON. Giving both is refused."""
    new, old = tmp_path / "camera.json", tmp_path / "preset.json"
    r = run("fit", "--depth", room_png, "--camera", "nyu", "-o", new, *FAST, "--seed", "2", "-q")
    assert r.exit_code == 0, r.output
    assert "deprecated" not in r.output
    r = run("fit", "--depth", room_png, "--preset", "nyu", "-o", old, *FAST, "--seed", "2", "-q")
    assert r.exit_code == 0, r.output
    assert "warning: --preset is deprecated; use --camera" in " ".join(r.output.split())
    a, b = (json.loads(p.read_text()) for p in (new, old))
    for doc in (a, b):
        doc.pop("timing_s")
    assert a == b and a["input"]["intrinsics_source"] == "preset:nyu"
    r = run("fit", "--depth", room_png, "--preset", "nyu", "--camera", "nyu", "-o", old, *FAST)
    assert r.exit_code == 2 and "give only --camera" in r.output
    # a command line refused for another reason says that in one line, without the warning
    r = run("fit", "--depth", room_png, "--preset", "nyu", "--unit", "cm", "-o", tmp_path / "no.json")
    refusal = "error: --unit does not apply to a depth map or a photo; leave it out"
    assert r.exit_code == 2 and r.output.strip().splitlines() == [refusal]
    rows = [line for line in run("fit", "--help").output.splitlines() if "│ --" in line]
    options = [row.strip("│ ").split()[0] for row in rows]
    assert "--camera" in options and "--preset" not in options


HEAVY = ("torch", "numba", "cv2", "open3d", "trimesh", "scipy", "PIL", "cuboidcli.learn")


START_UP = [["--help"], ["--version"], ["fit", "--help"], ["evaluate", "--help"]]


@pytest.mark.parametrize("args", START_UP, ids=" ".join)
def test_help_and_version_load_no_heavy_library(args):
    """``cuboids --help``, ``--version`` and a command's ``--help`` start in a fraction of a second: they
    import none of the numerical libraries (torch alone takes over a second to import)."""
    assert [m for m in _modules_loaded_by(args, HEAVY) if m.split(".")[0] in HEAVY or m in HEAVY] == []


def test_the_listed_help_of_a_lazy_group_is_its_own():
    """``cuboids --help`` lists ``train`` from a stored line, without importing it: the group's own line."""
    from cuboidcli.cli.main import LAZY_GROUPS, LAZY_HELP

    assert set(LAZY_HELP) == set(LAZY_GROUPS)
    for name, module in LAZY_GROUPS.items():
        group = __import__(module, fromlist=["group"]).group()
        assert LAZY_HELP[name] == group.help.splitlines()[0], name
    assert "Train the learned components" in runner.invoke(app, ["--help"]).output


def test_a_folder_of_depth_maps_leaves_out_the_photos_beside_them(tmp_path):
    """NYU- and TUM-like folders hold ``x_depth.png`` beside ``x_rgb.png``: the colour PNGs are said and
    left out, not fitted as depth maps and reported failed."""
    import shutil

    sample = ROOT / "cuboidcli" / "data" / "sample"
    frames = tmp_path / "frames"
    frames.mkdir()
    shutil.copy(sample / "sample_depth.png", frames / "a_depth.png")
    shutil.copy(sample / "sample.png", frames / "a_rgb.png")
    fit = ["fit", "--depth", str(frames), "-K", str(sample / "camera.json"), "--hypotheses=64"]
    result = runner.invoke(app, [*fit, "-o", str(tmp_path / "out")])
    assert result.exit_code == 0, result.output
    assert "left out 1 colour images" in result.output and "1 done, 0 skipped, 0 failed" in result.output
    assert sorted(p.name for p in (tmp_path / "out").glob("*.json")) == ["a_depth_cuboids.json"]


def test_output_into_an_existing_folder_and_a_name_without_json(tmp_path):
    """``-o DIR`` with an existing folder writes the frame's result into it, named after the input; a name
    without ``.json`` gets it (a file named like a folder would be a trap)."""
    sample = ROOT / "cuboidcli" / "data" / "sample"
    camera = str(sample / "camera.json")
    fit = ["fit", "--depth", str(sample / "sample_depth.png"), "-K", camera, "--hypotheses=64"]
    out = tmp_path / "out"
    out.mkdir()
    assert runner.invoke(app, [*fit, "-o", str(out), "-q"]).exit_code == 0
    assert [p.name for p in out.iterdir()] == ["sample_depth_cuboids.json"]
    assert runner.invoke(app, [*fit, "-o", str(tmp_path / "result"), "-q"]).exit_code == 0
    assert json.loads((tmp_path / "result.json").read_text())["schema"] == "cuboids/1"

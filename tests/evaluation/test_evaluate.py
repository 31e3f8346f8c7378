"""`cuboids evaluate` and the evaluation runner on tiny rendered datasets (80x60 depth maps)."""

from __future__ import annotations

import csv
import hashlib
import json
import math
import struct
import zlib
from dataclasses import replace
from pathlib import Path

import cv2
import h5py
import numpy as np
import pytest
from typer.testing import CliRunner

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.nyu import list_nyu_frames, read_mat_v5, read_splits
from cuboidcli.evaluation.presets import resolve
from cuboidcli.evaluation.provenance import weights_hashes
from cuboidcli.evaluation.raycast import render_depth
from cuboidcli.evaluation.runner import EvalSettings, evaluate, load_frames
from cuboidcli.fitting.config import FitConfig
from cuboidcli.io.dataset import write_cameras
from cuboidcli.io.depth import InputError
from cuboidcli.io.result import FitResult, write_result

SHARED_DATA = Path(__file__).resolve().parents[3] / "shared" / "data"
CAM = Camera.preset("nyu").scaled(0.125)  # 80x60
SMALL = FitConfig(hypotheses=48, max_cuboids=3, grid_step=2)
FAST_OPTS = ["--hypotheses", "48", "--max-cuboids", "3", "--grid-step", "2", "--device", "cpu"]


def scene(i: int) -> list[Cuboid]:
    """A room around the camera and one box on its floor, placed differently per frame."""
    room = Cuboid([0.0, -0.2, 2.5], [2.5, 1.5, 3.0], np.eye(3))
    a = math.radians(15.0 * i)
    rot = np.array([[math.cos(a), 0.0, math.sin(a)], [0.0, 1.0, 0.0], [-math.sin(a), 0.0, math.cos(a)]])
    box = Cuboid([-0.6 + 0.5 * i, 0.9, 3.0 + 0.3 * i], [0.5, 0.4, 0.4], rot)
    return [room, box]


def make_folder(root: Path, n: int = 3) -> list[str]:
    """The generic layout: depth/<name>.png (mm), cameras.json, cuboids/<name>.json (GT), splits.json."""
    names = [f"f{i}" for i in range(n)]
    for i, name in enumerate(names):
        depth_mm = np.round(render_depth(CAM, scene(i)) * 1000.0).astype(np.uint16)
        (root / "depth").mkdir(parents=True, exist_ok=True)
        cv2.imwrite(str(root / "depth" / f"{name}.png"), depth_mm)
        write_result(root / "cuboids" / f"{name}.json", FitResult(CAM, scene(i)))
    write_cameras(root, {name: CAM for name in names})
    (root / "splits.json").write_text(json.dumps({"test": names[1:], "train": names[:1]}))
    return names


@pytest.fixture(scope="module")
def folder(tmp_path_factory) -> Path:
    root = tmp_path_factory.mktemp("data")
    make_folder(root)
    return root


def metrics_json(out: Path) -> dict:
    return json.loads((out / "metrics.json").read_text())


def test_cli_writes_outputs_and_saved_fits_reevaluate_to_the_same_numbers(app, folder, tmp_path):
    out = tmp_path / "out"
    res = CliRunner().invoke(
        app, ["evaluate", str(folder), *FAST_OPTS, "--runs", "2", "-o", str(out), "--save-fits"]
    )
    assert res.exit_code == 0, res.output
    assert "AUC@20" in res.output and "|M|" in res.output
    doc = metrics_json(out)
    assert doc["seeds"] == [0, 1] and len(doc["runs"]) == 2 and len(doc["frames"]) == 6
    assert doc["config"]["hypotheses"] == 48 and doc["config"]["grid_step"] == 2
    assert doc["dataset"]["frames"] == ["f0", "f1", "f2"] and doc["machine"]["cpu_count"] >= 1
    assert set(doc["summary"]["oa_all_cm"]) == {"mean", "std"}
    assert doc["runs"][0]["frames_with_gt"] == 3 and "recall_iou0.5_pct" in doc["runs"][0]
    assert all(r["time_s"] > 0 for r in doc["frames"])
    with open(out / "frames.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert len(rows) == 6 and rows[0]["frame"] == "f0" and "auc5cm_pct" in rows[0]
    # the parsimony curve up to --max-cuboids 3, per run and as mean/std; no instance images: no objects
    curve = doc["runs"][0]["parsimony"]
    assert curve["k"] == [1, 2, 3] and len(curve["auc20cm_pct"]) == len(curve["coverage_pct"]) == 3
    assert curve["auc20cm_pct"][-1] == pytest.approx(doc["runs"][0]["auc20cm_pct"], rel=1e-12)
    assert curve["coverage_pct"][-1] == pytest.approx(doc["runs"][0]["coverage_pct"], rel=1e-12)
    assert set(doc["summary"]["parsimony"]) == {"mean", "std"}
    assert doc["summary"]["parsimony"]["mean"]["k"] == [1, 2, 3]
    assert "parsimony: first k cuboids" in res.output
    assert "object_recall_pct" not in doc["runs"][0] and "object_recall_pct" not in rows[0]
    # re-evaluate run 0 from the saved files: identical numbers, time included (read from the files)
    again = tmp_path / "again"
    saved = out / "fits" / "seed0"
    res = CliRunner().invoke(app, ["evaluate", str(folder), "--fits", str(saved), "-o", str(again)])
    assert res.exit_code == 0, res.output
    assert metrics_json(again)["runs"][0] == doc["runs"][0]


def test_exact_ground_truth_fits_score_perfectly(app, folder, tmp_path):
    fits = tmp_path / "gt_fits"
    for i in range(3):
        write_result(fits / f"f{i}.json", FitResult(CAM, scene(i), timing_s={"total": 0.25}))
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["evaluate", str(folder), "--fits", str(fits), "-o", str(out)])
    assert res.exit_code == 0, res.output
    run = metrics_json(out)["runs"][0]
    assert run["cuboids"] == 2.0 and run["coverage_pct"] == 100.0 and run["time_s"] == 0.25
    assert run["oa_all_cm"] < 0.1  # depth PNGs are rounded to millimetres
    assert run["auc20cm_pct"] > 99.5 and run["auc5cm_pct"] > 98.0
    for key in ("recall_iou0.25_pct", "precision_iou0.25_pct", "recall_iou0.5_pct", "precision_iou0.5_pct"):
        assert run[key] == 100.0


def test_instance_images_give_object_recall_and_precision(app, tmp_path):
    """A folder with instances/<name>.png (uint16 ids beyond 255) scored with saved fits: the ground truth
    explains every object; one extra cuboid far away lowers precision only."""
    from cuboidcli.synth.render import render_boxes

    data, fits = tmp_path / "data", tmp_path / "fits"
    (data / "depth").mkdir(parents=True)
    (data / "instances").mkdir()
    names = ["f0", "f1"]
    far_away = Cuboid([0.0, 0.0, 30.0], [0.5, 0.5, 0.5], np.eye(3))
    for i, name in enumerate(names):
        depth, inst = render_boxes(scene(i), CAM)
        cv2.imwrite(str(data / "depth" / f"{name}.png"), np.round(depth * 1000.0).astype(np.uint16))
        cv2.imwrite(str(data / "instances" / f"{name}.png"), (300 * inst).astype(np.uint16))
        pred = scene(i) + ([far_away] if i == 1 else [])
        write_result(fits / f"{name}.json", FitResult(CAM, pred, timing_s={"total": 0.1}))
    write_cameras(data, {name: CAM for name in names})
    frames, _ = load_frames(data)
    assert np.unique(frames[0].instances()).tolist() == [300, 600]  # the room fills the background
    out = tmp_path / "out"
    res = CliRunner().invoke(
        app, ["evaluate", str(data), "--fits", str(fits), "--max-cuboids", "4", "-o", str(out)]
    )
    assert res.exit_code == 0, res.output
    assert "object recall" in res.output and "parsimony" in res.output
    doc = metrics_json(out)
    run = doc["runs"][0]
    assert run["object_recall_pct"] == 100.0 and run["object_precision_pct"] == pytest.approx(100 * 4 / 5)
    assert run["objects_eligible"] == 4 and run["frames_with_instances"] == 2
    assert doc["summary"]["object_precision_pct"]["mean"] == pytest.approx(80.0)
    assert [r["object_precision_pct"] for r in doc["frames"]] == [100.0, pytest.approx(200 / 3)]
    with open(out / "frames.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert [float(r["object_recall_pct"]) for r in rows] == [100.0, 100.0]
    assert [int(r["objects_eligible"]) for r in rows] == [2, 2]
    curve = run["parsimony"]  # the fits record no settings: K = --max-cuboids
    assert curve["k"] == [1, 2, 3, 4]
    assert curve["coverage_pct"] == [100.0] * 4  # the first cuboid, the room, surrounds the camera
    assert curve["auc5cm_pct"][0] < curve["auc5cm_pct"][1] == curve["auc5cm_pct"][3]
    assert curve["auc5cm_pct"][3] == pytest.approx(run["auc5cm_pct"], rel=1e-12)


def test_workers_give_the_same_numbers_as_one_process(folder):
    frames, _ = load_frames(folder)
    one = evaluate(frames, SMALL, EvalSettings(workers=1))
    two = evaluate(frames, SMALL, EvalSettings(workers=2))
    strip = [{k: v for k, v in m.row().items() if k != "time_s"} for m in one.frames[0]]
    assert strip == [{k: v for k, v in m.row().items() if k != "time_s"} for m in two.frames[0]]
    assert [m.cuboids for m in one.frames[0]] == [m.cuboids for m in two.frames[0]]
    assert sum(m.cuboids for m in one.frames[0]) >= 3


def test_local_ray_gives_the_same_numbers_as_one_process(folder):
    pytest.importorskip("ray")
    frames, _ = load_frames(folder)
    one = evaluate(frames, SMALL, EvalSettings(workers=1))
    ray = evaluate(frames, SMALL, EvalSettings(workers=2, ray=""))  # a local Ray of 2 CPUs
    strip = [{k: v for k, v in m.row().items() if k != "time_s"} for m in one.frames[0]]
    assert strip == [{k: v for k, v in m.row().items() if k != "time_s"} for m in ray.frames[0]]
    assert ray.counts.line() == "3 done, 0 skipped, 0 failed"


def test_an_interrupted_evaluation_resumes_from_its_saved_fits(folder, tmp_path):
    frames, _ = load_frames(folder)
    settings = EvalSettings(save_fits_dir=tmp_path / "fits")
    first = evaluate(frames, SMALL, settings)
    assert first.counts.line() == "3 done, 0 skipped, 0 failed"
    (tmp_path / "fits" / "seed0" / "f2.json").unlink()  # the run was interrupted before this frame
    again = evaluate(frames, SMALL, settings)
    assert again.counts.line() == "1 done, 2 skipped, 0 failed"
    # Scored from the saved files: the same rows, times included (they are read from the files).
    assert [m.row() for m in again.frames[0][:2]] == [m.row() for m in first.frames[0][:2]]
    assert [m.cuboids for m in again.frames[0]] == [m.cuboids for m in first.frames[0]]
    # Other settings, or --no-skip-existing, fit every frame again.
    other = evaluate(frames, replace(SMALL, max_cuboids=2), settings)
    assert other.counts.done == 3
    redo = evaluate(frames, SMALL, replace(settings, skip_existing=False))
    assert redo.counts.done == 3


def test_a_failed_frame_is_reported_and_left_out_of_the_metrics(app, tmp_path):
    root = tmp_path / "data"
    make_folder(root)
    (root / "depth" / "f1.png").write_bytes(b"not a png")
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["evaluate", str(root), *FAST_OPTS, "-o", str(out)])
    assert res.exit_code == 1, res.output
    assert "failed f1:" in res.output and "cannot decode image" in res.output
    assert "2 done, 0 skipped, 1 failed" in res.output
    doc = metrics_json(out)
    assert [r["frame"] for r in doc["frames"]] == ["f0", "f2"] and doc["runs"][0]["frames"] == 2
    assert doc["failed_frames"][0]["frame"] == "f1" and "cannot decode" in doc["failed_frames"][0]["error"]


def test_frame_selection_split_names_and_limit(folder):
    assert [f.name for f in load_frames(folder, split="test")[0]] == ["f1", "f2"]
    assert [f.name for f in load_frames(folder, names=["f2", "f0"])[0]] == ["f2", "f0"]
    assert [f.name for f in load_frames(folder, limit=2)[0]] == ["f0", "f1"]


@pytest.mark.parametrize(
    "args, message",
    [
        (["--frames", "nope"], "no frame named 'nope'"),
        (["--save-fits"], "--save-fits writes into the output folder"),
        (["--preset", "magic"], "unknown preset 'magic'"),
        (["--auc", "20,x"], "comma-separated numbers"),
        (["--runs", "0"], "--runs must be at least 1"),
        (["--split", "holdout"], "splits.json has only"),
    ],
)
def test_cli_errors_are_one_line(app, folder, args, message):
    res = CliRunner().invoke(app, ["evaluate", str(folder), *args])
    assert res.exit_code == 2
    assert message in res.output and res.output.strip().count("\n") <= 1


def test_unusable_estimator_settings_fail_before_any_frame(folder):
    frames, _ = load_frames(folder)
    with pytest.raises(InputError, match="cannot run sampler 'bogus'"):
        evaluate(frames, FitConfig(sampler="bogus"), EvalSettings())


def test_weights_of_learned_parts_are_hashed(tmp_path):
    weights = tmp_path / "solver_v1.pt"
    weights.write_bytes(b"not really a checkpoint")
    hashes = weights_hashes(FitConfig(solver="neural"), tmp_path)
    sha = hashlib.sha256(b"not really a checkpoint").hexdigest()
    assert hashes == {"solver": {"path": str(weights), "sha256": sha}}
    assert hashes == weights_hashes(FitConfig(solver="neural"), weights)
    assert weights_hashes(FitConfig(), tmp_path) == {}  # nothing learned in use


def test_presets_combine_and_options_override_them():
    config, auc_cm, applied = resolve("seqransac,outdoor")
    assert (config.sampler, config.occlusion_aware, config.refine) == ("sequential", False, False)
    assert (config.tau_sq_m2, config.a_min, config.a_max) == (0.04, 2.0, 30.0)
    assert auc_cm == (50.0, 10.0) and applied == ["seqransac", "outdoor"]
    assert resolve("seqransac-oai")[0].occlusion_aware is True
    assert resolve("ours-neural")[0].solver == "neural"
    assert resolve("uniform,paper")[0] == FitConfig(
        sampler="uniform",
        refine=False,
        local_fraction=0.0,
        max_batches=1,
        hypotheses=4096,
        slab_max_m=None,
        theta_log_factor=9.0,
        align="free",
    )
    assert resolve(None)[0] == FitConfig()


def test_cli_options_override_preset(app, folder, tmp_path):
    out = tmp_path / "out"
    opts = "--preset seqransac-oai,outdoor --auc 30 --no-oai --refine --limit 1 --seed 7".split()
    res = CliRunner().invoke(app, ["evaluate", str(folder), *opts, *FAST_OPTS, "-o", str(out)])
    assert res.exit_code == 0, res.output
    doc = metrics_json(out)
    assert doc["auc_cm"] == [30.0] and "auc30cm_pct" in doc["runs"][0] and doc["seeds"] == [7]
    assert doc["config"]["occlusion_aware"] is False and doc["config"]["tau_sq_m2"] == 0.04
    assert doc["config"]["refine"] is True and doc["presets"] == ["seqransac-oai", "outdoor"]


# NYU Depth v2 files: written here in the official layout


def _mat_v5_element(mtype: int, payload: bytes) -> bytes:
    return struct.pack("<II", mtype, len(payload)) + payload + b"\0" * ((-len(payload)) % 8)


def _mat_v5_matrix(name: str, values: np.ndarray, stored: str) -> bytes:
    """miMATRIX of class double holding a column vector, values stored as ``stored`` (f8 or u2)."""
    flags = _mat_v5_element(6, struct.pack("<II", 6, 0))  # mxDOUBLE_CLASS
    dims = _mat_v5_element(5, struct.pack("<ii", len(values), 1))
    name_el = _mat_v5_element(1, name.encode())
    mtype = {"f8": 9, "u2": 4}[stored]
    real = _mat_v5_element(mtype, values.astype("<" + stored).tobytes(order="F"))
    return _mat_v5_element(14, flags + dims + name_el + real)


def write_splits_v5(path, test: np.ndarray, train: np.ndarray, compress: bool = True) -> None:
    header = b"MATLAB 5.0 MAT-file, written by the cuboids tests".ljust(116, b" ") + b"\0" * 8
    header += struct.pack("<H", 0x0100) + b"IM"
    body = b""
    for name, values, stored in (("testNdxs", test, "u2"), ("trainNdxs", train, "f8")):
        el = _mat_v5_matrix(name, values, stored)
        body += struct.pack("<II", 15, len(zlib.compress(el))) + zlib.compress(el) if compress else el
    path.write_bytes(header + body)


def write_labeled_mat(path, depths: np.ndarray, images: np.ndarray) -> None:
    """A v7.3-style file: HDF5 after a 512-byte MATLAB header, arrays transposed as MATLAB stores them."""
    with h5py.File(path, "w", userblock_size=512) as f:
        f.create_dataset("depths", data=depths.transpose(0, 2, 1))  # (N, W, H)
        f.create_dataset("images", data=images.transpose(0, 3, 2, 1))  # (N, 3, W, H)
    with open(path, "r+b") as fh:
        fh.write(b"MATLAB 7.3 MAT-file, written by the cuboids tests".ljust(128, b" "))


@pytest.mark.parametrize("compress", [True, False])
def test_splits_reader_gives_paper_splits(tmp_path, compress):
    rng = np.random.default_rng(0)
    order = rng.permutation(1449) + 1  # 1-based frame numbers
    test, train = np.sort(order[:654]), np.sort(order[654:])
    write_splits_v5(tmp_path / "splits.mat", test, train, compress)
    raw = read_mat_v5(tmp_path / "splits.mat")
    assert raw["testNdxs"].shape == (654, 1) and raw["testNdxs"].dtype == np.float64
    splits = read_splits(tmp_path / "splits.mat")
    assert len(splits["test"]) == 654 and len(splits["train"]) == 600 and len(splits["val"]) == 195
    assert splits["test"] == list(test - 1)
    assert splits["train"] + splits["val"] == list(train - 1)


def test_splits_reader_accepts_a_v73_hdf5_file(tmp_path):
    with h5py.File(tmp_path / "splits.mat", "w") as f:  # MATLAB v7.3 stores column vectors as (1, N)
        f.create_dataset("testNdxs", data=np.array([[3.0, 1.0]]))
        f.create_dataset("trainNdxs", data=np.array([[2.0, 4.0, 5.0]]))
    assert read_splits(tmp_path / "splits.mat") == {"test": [2, 0], "train": [1, 3, 4], "val": []}


def test_labeled_mat_reader_undoes_matlab_transpose(tmp_path):
    rng = np.random.default_rng(1)
    depths = rng.uniform(0.5, 5.0, size=(5, 12, 16)).astype(np.float32)  # (N, H, W)
    images = rng.integers(0, 255, size=(5, 12, 16, 3), dtype=np.uint8)
    write_labeled_mat(tmp_path / "nyu_depth_v2_labeled.mat", depths, images)
    write_splits_v5(tmp_path / "splits.mat", np.array([2, 5]), np.array([1, 3, 4]))
    frames = list_nyu_frames(tmp_path, "test")
    assert [f.name for f in frames] == ["nyu_0002", "nyu_0005"]
    assert (frames[0].camera.width, frames[0].camera.height) == (16, 12)
    np.testing.assert_array_equal(frames[1].depth_m(), depths[4])
    np.testing.assert_array_equal(frames[0].rgb(), images[1])
    assert [f.name for f in list_nyu_frames(tmp_path, "train")] == ["nyu_0001", "nyu_0003", "nyu_0004"]
    assert len(list_nyu_frames(tmp_path / "nyu_depth_v2_labeled.mat", None)) == 5


def test_nyu_labeled_mat_folder_is_evaluated_by_split(app, tmp_path):
    cam = Camera.preset("nyu").with_size(80, 60)  # what the reader assumes for an 80x60 file
    depths = np.stack([render_depth(cam, scene(i)) for i in range(4)])
    images = np.zeros((4, 60, 80, 3), dtype=np.uint8)
    write_labeled_mat(tmp_path / "nyu_depth_v2_labeled.mat", depths, images)
    write_splits_v5(tmp_path / "splits.mat", np.array([2, 4]), np.array([1, 3]))
    fits = tmp_path / "fits"
    for i in range(4):
        write_result(fits / f"nyu_{i + 1:04d}.json", FitResult(cam, scene(i), timing_s={"total": 1.0}))
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["evaluate", str(tmp_path), "--fits", str(fits), "-o", str(out)])
    assert res.exit_code == 0, res.output
    doc = metrics_json(out)
    assert doc["dataset"]["split"] == "test" and doc["dataset"]["frames"] == ["nyu_0002", "nyu_0004"]
    assert doc["runs"][0]["oa_all_cm"] < 1e-3 and doc["runs"][0]["auc5cm_pct"] > 99.9


@pytest.mark.skipif(not SHARED_DATA.is_dir(), reason="../shared/data is not available")
def test_real_frames_of_shared_data_are_evaluable():
    for sub, expected in (("nyu", {"basement_00000", "dining_crop", "livingroom"}), ("tum", {"tum"})):
        frames, info = load_frames(SHARED_DATA / sub)
        assert expected <= set(info["frames"])
        frames = [f for f in frames if f.name in expected]
        report = evaluate(frames, FitConfig(hypotheses=32, max_cuboids=2), EvalSettings())
        for m in report.frames[0]:
            assert m.n_points > 50_000  # full resolution, holes excluded
            assert 0.0 <= m.coverage <= 1.0 and m.time_s > 0
            if m.cuboids:
                assert math.isfinite(m.oa_all_m) and 0.0 <= m.auc[20.0].value <= 1.0


def test_rgb_input_fits_estimated_depth_and_scores_against_true_depth(app, folder, tmp_path):
    """--rgb: frames without an image fail in one line; with images the fit uses the depth network's
    prediction (here an untrained tiny net), is scored against the true depth, and times the estimation."""
    import shutil

    import torch

    from cuboidcli.nets.checkpoint import checkpoint_dict
    from cuboidcli.nets.depth import DepthNet, DepthNetConfig

    res = CliRunner().invoke(app, ["evaluate", str(folder), "--rgb", *FAST_OPTS])
    assert res.exit_code == 2 and "needs an RGB image" in res.output

    data = tmp_path / "data"
    shutil.copytree(folder, data)
    (data / "rgb").mkdir()
    for name in ("f0", "f1", "f2"):
        depth = cv2.imread(str(data / "depth" / f"{name}.png"), cv2.IMREAD_UNCHANGED)
        grey = np.clip(depth / 30.0, 0, 255).astype(np.uint8)
        cv2.imwrite(str(data / "rgb" / f"{name}.png"), np.stack([grey] * 3, -1))
    torch.manual_seed(0)
    net = DepthNet(DepthNetConfig(channels=(4, 8, 8, 8, 8), input_height=64, input_width=80))
    torch.save(checkpoint_dict(net), tmp_path / "depth.pt")
    frames, _ = load_frames(data)
    settings = EvalSettings(rgb=True, depth_model=tmp_path / "depth.pt")
    report = evaluate(frames, SMALL, settings)
    from_depth = evaluate(frames, SMALL, EvalSettings())
    assert len(report.frames[0]) == 3
    # the untrained net's depth is far from the truth: the cuboids fit it, not the true points
    assert report.runs[0]["auc20cm_pct"] < from_depth.runs[0]["auc20cm_pct"]
    res = CliRunner().invoke(
        app, ["evaluate", str(data), "--rgb", "--depth-model", str(tmp_path / "depth.pt"), *FAST_OPTS]
    )
    assert res.exit_code == 0, res.output
    assert "from RGB" in res.output
    res = CliRunner().invoke(app, ["evaluate", str(data), "--depth-model", str(tmp_path / "depth.pt")])
    assert res.exit_code == 2 and "applies to --rgb" in res.output

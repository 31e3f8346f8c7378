"""cuboidcli.job: one Job fits one frame and every frame of a folder alike (fit_task is its one task), and a
rerun skips the frames whose outputs are complete. Frames are 80x60 renders, fits are small."""

from __future__ import annotations

import json
import shutil
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.raycast import render_depth
from cuboidcli.fitting.config import FitConfig
from cuboidcli.job import Job, fit_task, folder_tasks
from cuboidcli.load import LoadOptions

CAM = Camera.preset("nyu").scaled(0.125)  # 80x60
K = f"{CAM.fx},{CAM.fy},{CAM.cx},{CAM.cy}"
CONFIG = FitConfig(hypotheses=48, max_cuboids=3, grid_step=2, device="cpu")


@pytest.fixture(scope="module")
def frames(tmp_path_factory):
    root = tmp_path_factory.mktemp("frames")
    room = Cuboid([0.0, -0.2, 2.5], [2.5, 1.5, 3.0], np.eye(3))
    for i in range(2):
        box = Cuboid([-0.5 + 0.5 * i, 0.9, 3.0], [0.5, 0.4, 0.4], np.eye(3))
        cv2.imwrite(
            str(root / f"f{i}.png"), np.round(render_depth(CAM, [room, box]) * 1000).astype(np.uint16)
        )
    return root


def test_one_frame_and_the_folder_task_give_the_same_result(frames, tmp_path):
    job = Job(CONFIG, options=LoadOptions(intrinsics=K), source="depth", outputs=("glb",))
    frame = job.load(frames / "f0.png")
    assert frame.meta["depth"] == str(frames / "f0.png") and frame.meta["depth_source"] == "depth map"
    written = job.save(job.fit(frame), tmp_path / "one.json")
    assert written == [tmp_path / "one.json", tmp_path / "one.glb"]
    outcome = fit_task(job, str(frames / "f0.png"), str(tmp_path / "task.json"))
    assert outcome.status == "done" and outcome.value[0] >= 1 and outcome.value[2] == "depth map"
    one, task = (json.loads((tmp_path / n).read_text()) for n in ("one.json", "task.json"))
    assert one["cuboids"] == task["cuboids"] and one["settings"] == task["settings"]
    # how the input was read: the loading options that apply to a depth map
    assert one["settings"]["load"] == {"intrinsics": K, "camera": None, "depth_scale": None}
    assert job.expected(tmp_path / "task.json") == [tmp_path / "task.glb", tmp_path / "task.json"]


def test_folder_tasks_skip_complete_frames_of_the_same_settings(frames, tmp_path):
    folder = tmp_path / "frames"
    shutil.copytree(frames, folder)
    (folder / "cameras.json").write_text(json.dumps({"fx": CAM.fx, "fy": CAM.fy, "cx": CAM.cx, "cy": CAM.cy}))
    job = Job(CONFIG, source="depth").in_folder(folder)
    assert job.options.intrinsics == str(folder / "cameras.json")
    given = Job(CONFIG, options=LoadOptions(intrinsics=K), source="depth")
    assert given.in_folder(folder).options.intrinsics == K  # -K wins
    files = sorted(folder.glob("*.png"))
    out = tmp_path / "out"
    tasks, skipped = folder_tasks(job, files, out, skip_existing=True)
    assert skipped == [] and [t[1:] for t in tasks] == [
        (str(files[0]), str(out / "f0_cuboids.json")),
        (str(files[1]), str(out / "f1_cuboids.json")),
    ]
    assert fit_task(*tasks[0]).status == "done"
    tasks, skipped = folder_tasks(job, files, out, skip_existing=True)
    assert skipped == [files[0]] and [t[1] for t in tasks] == [str(files[1])]
    assert len(folder_tasks(job, files, out, skip_existing=False)[0]) == 2
    other = replace(job, config=replace(CONFIG, seed=1))
    assert folder_tasks(other, files, out, skip_existing=True)[1] == []  # other settings: fitted again
    with_glb = replace(job, outputs=("glb",))
    assert folder_tasks(with_glb, files, out, skip_existing=True)[1] == []  # its GLB is missing
    scaled = replace(job, options=replace(job.options, depth_scale=0.001))
    assert folder_tasks(scaled, files, out, skip_existing=True)[1] == []  # read otherwise: fitted again


def test_a_bad_frame_fails_with_one_line(tmp_path):
    bad = tmp_path / "bad.png"
    cv2.imwrite(str(bad), np.zeros((60, 80), np.uint8))
    job = Job(CONFIG, options=LoadOptions(intrinsics=K), source="depth")
    outcome = fit_task(job, str(bad), str(tmp_path / "bad.json"))
    assert outcome.status == "failed" and "8-bit" in outcome.message
    assert not (tmp_path / "bad.json").exists()


def test_a_folder_of_rooms_as_scannet_lays_them_out(tmp_path):
    """``scans/sceneXXXX_XX/sceneXXXX_XX_vh_clean_2.ply``, one level deeper, beside plain scan files: each
    room once (ScanNet's cleaned mesh of several PLYs), folders without one scan file left out."""
    from cuboidcli.job import is_rooms_folder, rooms_in

    def ply(path):
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nend_header\n")
        return path

    scans = tmp_path / "scans"
    deep = ply(scans / "scene0000_00" / "scene0000_00_vh_clean_2.ply")
    ply(scans / "scene0000_00" / "scene0000_00_vh_clean.ply")
    single = ply(scans / "scene0001_00" / "room.ply")
    ply(scans / "two" / "a.ply")
    ply(scans / "two" / "b.ply")
    top = ply(scans / "loose.ply")
    (scans / "empty").mkdir()
    assert rooms_in(scans) == [top, deep, single]
    assert is_rooms_folder(scans)


def _empty_ply(path):
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text("ply\nformat ascii 1.0\nelement vertex 0\nproperty float x\nend_header\n")
    return path


def test_scannets_root_folder_gives_the_rooms_of_its_scans(tmp_path):
    """ScanNet's root (``scans/``, ``scans_test/`` and its label files) is a folder of rooms two levels down;
    a third level is not searched."""
    from cuboidcli.job import is_rooms_folder, rooms_in

    root = tmp_path / "ScanNet"
    a = _empty_ply(root / "scans" / "scene0000_00" / "scene0000_00_vh_clean_2.ply")
    _empty_ply(root / "scans" / "scene0000_00" / "scene0000_00_vh_clean.ply")
    b = _empty_ply(root / "scans_test" / "scene0707_00" / "scene0707_00_vh_clean_2.ply")
    _empty_ply(root / "deeper" / "still" / "scene" / "room.ply")
    (root / "scannetv2-labels.combined.tsv").write_text("id\tcategory\n")
    assert rooms_in(root) == [a, b]
    assert is_rooms_folder(root)
    assert rooms_in(root, levels=1) == []


def test_rooms_that_share_a_file_name_get_results_of_their_own(tmp_path):
    """Two rooms saved as room.ply in their own folders, and a.png beside a.npy, would write one result
    JSON over the other."""
    from cuboidcli.export.files import result_names

    a = _empty_ply(tmp_path / "scans" / "kitchen" / "room.ply")
    b = _empty_ply(tmp_path / "scans" / "office" / "room.ply")
    c = _empty_ply(tmp_path / "scans" / "lounge.ply")
    names = result_names([a, b, c])
    assert names == ["kitchen_room_ply_cuboids.json", "office_room_ply_cuboids.json", "lounge_cuboids.json"]
    pair = [tmp_path / "a.png", tmp_path / "a.npy", tmp_path / "b.png"]
    assert result_names(pair) == ["a_png_cuboids.json", "a_npy_cuboids.json", "b_cuboids.json"]
    deep = [tmp_path / "x" / "y" / "r.ply", tmp_path / "z" / "y" / "r.ply", tmp_path / "x" / "y" / "r.ply"]
    assert result_names(deep) == ["x_y_r_ply_0_cuboids.json", "z_y_r_ply_cuboids.json",
                                  "x_y_r_ply_2_cuboids.json"]  # fmt: skip
    job = Job(CONFIG)
    tasks, skipped = folder_tasks(job, [a, b, c], tmp_path / "out", skip_existing=True)
    assert [Path(t[2]).name for t in tasks] == names and skipped == []

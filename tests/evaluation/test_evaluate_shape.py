"""Shape measurements of `cuboids evaluate`: axis angles to gravity and the room's axes, support of the
visible faces, the gravity error, and box recall / precision at 3D IoU 0.25; on rendered scenes."""

from __future__ import annotations

import csv
import json
import math

import numpy as np
import pytest
from typer.testing import CliRunner

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.aggregate import aggregate
from cuboidcli.evaluation.metrics import frame_metrics
from cuboidcli.evaluation.runner import EvalSettings, evaluate, load_frames
from cuboidcli.evaluation.shape import (
    ShapeMetrics,
    axis_angles,
    gravity_from_saved,
    synthetic_reference,
    visible_faces,
)
from cuboidcli.evaluation.shape_summary import gravity_summary, shape_summary
from cuboidcli.fitting.config import FitConfig
from cuboidcli.geometry.gravity import given_gravity
from cuboidcli.io.result import FitResult, write_result
from cuboidcli.synth.render import render_boxes
from tests.conftest import simple_room, yaw
from tests.evaluation.test_evaluate import CAM as SMALL_CAM
from tests.evaluation.test_evaluate import make_folder, scene

CAM = Camera.preset("nyu").scaled(0.25)  # 160x120
#: world_from_camera of a level camera 1.5 m above the floor: the rows of the rotation are the room's
#: x, y, z (up) axes in camera coordinates; up is the camera's -y.
LEVEL_POSE = np.array([[1.0, 0, 0, 0], [0, 0, 1.0, 0], [0, -1.0, 0, 1.5], [0, 0, 0, 1.0]])
LEVEL = synthetic_reference(LEVEL_POSE)
#: Estimate gravity on every other pixel (the default grid of 8 leaves too few normals at 160x120).
GRID2 = FitConfig(grid_step=2)


def pitch(deg: float) -> np.ndarray:
    """Rotation about the camera's x axis (tilts the vertical)."""
    c, s = math.cos(math.radians(deg)), math.sin(math.radians(deg))
    return np.array([[1.0, 0.0, 0.0], [0.0, c, -s], [0.0, s, c]])


@pytest.fixture(scope="module")
def room():
    """simple_room (floor, back wall, left wall, cabinet, a box yawed 0.4 rad) rendered exactly."""
    boxes = simple_room()
    depth, instances = render_boxes(boxes, CAM)
    return boxes, depth, instances


def shape_of(depth, cuboids, **kw):
    m = frame_metrics("f", depth, CAM, cuboids, shape=True, **kw)
    return m, m.shape


# ---------------------------------------------------------------- angles


def test_synthetic_reference_of_a_level_camera():
    assert LEVEL.source == "synthetic"
    np.testing.assert_allclose(LEVEL.up, [0.0, -1.0, 0.0], atol=1e-12)
    np.testing.assert_allclose(LEVEL.frame, [[0, 1, 0], [-1, 0, 0], [0, 0, 1]], atol=1e-12)


@pytest.mark.parametrize(
    "rotation, gravity_deg, manhattan_deg",
    [
        (np.eye(3), 0.0, 0.0),
        (yaw(math.radians(10.0)), 0.0, 10.0),
        (yaw(math.radians(45.0)), 0.0, 45.0),
        (yaw(math.radians(90.0)), 0.0, 0.0),  # a quarter turn: the axes are permuted, still aligned
        (yaw(math.radians(-7.0)) @ pitch(0.0), 0.0, 7.0),
        (pitch(5.0), 5.0, 5.0),
        (pitch(5.0) @ yaw(math.radians(20.0)), 5.0, None),  # tilted and yawed: at least 20 degrees
    ],
)
def test_axis_angles(rotation, gravity_deg, manhattan_deg):
    g, m = axis_angles(rotation, LEVEL.up, LEVEL.frame)
    assert g == pytest.approx(gravity_deg, abs=1e-9)
    if manhattan_deg is None:
        assert m >= 20.0
    else:
        assert m == pytest.approx(manhattan_deg, abs=1e-9)
    g2, m2 = axis_angles(rotation, LEVEL.up, None)  # no room frame: the Manhattan angle is undefined
    assert g2 == g and math.isnan(m2)


# ---------------------------------------------------------------- rendered frames


def test_exact_room_is_aligned_and_supported(room):
    boxes, depth, _ = room
    m, s = shape_of(depth, boxes, known_gravity=LEVEL, config=GRID2)
    assert s.reference == "synthetic"
    np.testing.assert_allclose(s.angle_gravity_deg, 0.0, atol=1e-9)
    np.testing.assert_allclose(s.angle_manhattan_deg, [0, 0, 0, 0, math.degrees(0.4)], atol=1e-9)
    assert s.slab.tolist() == [True, True, True, False, False]
    assert (s.visible_px > 100).all()
    # points within tau of two touching boxes go to one of them: a few pixels short of 100 %
    assert (s.support > 0.98).all()
    row = m.row()
    assert row["gravity_ref"] == "synthetic" and row["slabs"] == 3 and row["slabs_within_3deg_pct"] == 100.0
    assert row["axis_angle_gravity_median_deg"] == 0.0 and row["axis_angle_manhattan_median_deg"] == 0.0
    assert row["support_median_pct"] > 98.0
    # the gravity the depth map gives (estimated as an aligned fit would) against the known one
    assert row["gravity_error_of"] == "estimated" and row["gravity_error_deg"] < 0.05
    cub = m.cuboid_rows()
    assert [c["cuboid"] for c in cub] == [0, 1, 2, 3, 4] and cub[4][
        "axis_angle_manhattan_deg"
    ] == pytest.approx(math.degrees(0.4))
    assert cub[0]["slab"] is True and cub[0]["support_pct"] == pytest.approx(100.0 * s.support[0])


def test_a_yawed_prediction_measures_its_yaw(room):
    boxes, depth, _ = room
    cabinet = boxes[3]
    turned = Cuboid(cabinet.center, cabinet.half_size, yaw(math.radians(10.0)))
    _, s = shape_of(depth, boxes[:3] + [turned], known_gravity=LEVEL)
    assert s.angle_gravity_deg[3] == pytest.approx(0.0, abs=1e-9)
    assert s.angle_manhattan_deg[3] == pytest.approx(10.0, abs=1e-9)


def test_an_oversized_box_is_poorly_supported(room):
    """The cabinet twice as wide: its widened faces hang in front of the wall and the floor (where the floor
    ends there is no depth: not counted). Grown by half in every direction, its faces lie 15 cm off the
    cabinet's surface (tau ~ 6.3 cm): nothing backs them."""
    boxes, depth, _ = room
    cabinet = boxes[3]
    _, exact = shape_of(depth, boxes)
    assert exact.support[3] > 0.98
    wide = Cuboid(cabinet.center, cabinet.half_size * [2.0, 1.0, 1.0], cabinet.rotation)
    _, s = shape_of(depth, boxes[:3] + [wide])
    assert 0.5 < s.support[3] < 0.7
    assert s.visible_px[3] > 1.4 * exact.visible_px[3] and s.supported_px[3] < exact.supported_px[3]
    big = Cuboid(cabinet.center, cabinet.half_size * 1.5, cabinet.rotation)
    _, s = shape_of(depth, boxes[:3] + [big])
    assert s.support[3] < 0.01 and s.visible_px[3] > exact.visible_px[3]


def test_faces_hidden_behind_nearer_points_are_not_counted(room):
    """Only the back wall predicted: the cabinet and the box hide parts of it; those pixels say nothing
    about the wall and are left out, so its support stays near 100 %."""
    boxes, depth, instances = room
    wall = boxes[1]
    owner, _ = visible_faces(CAM, [wall])
    wall_px = int((instances == 2).sum())
    assert (owner == 0).sum() > wall_px + 300  # the wall's face covers much more than what is seen of it
    _, s = shape_of(depth, [wall])
    assert s.visible_px[0] == pytest.approx(wall_px, rel=0.02)  # (+ floor points within tau of the wall)
    assert s.support[0] > 0.99


def test_pixels_without_depth_are_not_counted(room):
    boxes, depth, _ = room
    _, full = shape_of(depth, boxes)
    holes = depth.copy()
    holes[:, : CAM.width // 2] = 0.0
    _, s = shape_of(holes, boxes)
    assert s.visible_px[1] < 0.7 * full.visible_px[1]
    assert s.support[1] > 0.98


def test_the_fits_gravity_is_the_reference_and_its_error_is_measured(room):
    """A fit that used a gravity tilted by 3 degrees: upright boxes are 3 degrees off its up; the given
    gravity has no room frame, so the Manhattan angles are undefined."""
    boxes, depth, _ = room
    tilted = pitch(3.0) @ np.array([0.0, 1.0, 0.0])
    m, s = shape_of(depth, boxes, known_gravity=LEVEL, fit_gravity=given_gravity(tilted))
    assert s.reference == "fit" and s.gravity_error_of == "fit"
    assert s.gravity_error_deg == pytest.approx(3.0, abs=1e-9)
    np.testing.assert_allclose(s.angle_gravity_deg[:4], 3.0, atol=1e-9)
    assert np.isnan(s.angle_manhattan_deg).all()
    row = m.row()
    assert math.isnan(row["slabs_within_3deg_pct"]) and row["slabs"] == 0


def test_gravity_estimated_from_the_depth_when_nothing_else_is_known(room):
    boxes, depth, _ = room
    m, s = shape_of(depth, boxes, config=GRID2)
    assert s.reference == "estimated" and s.gravity_error_of == ""
    assert (s.angle_gravity_deg < 0.05).all()
    assert "gravity_error_deg" not in m.row()


def test_without_any_gravity_the_angles_are_empty(room):
    """A grid of 8 px leaves 20x15 cells at 160x120: no reliable estimate, no reference."""
    boxes, depth, _ = room
    m, s = shape_of(depth, boxes, config=FitConfig(grid_step=8))
    assert s.reference == "none" and np.isnan(s.angle_gravity_deg).all()
    row = m.row()
    assert math.isnan(row["axis_angle_gravity_median_deg"]) and row["support_median_pct"] > 98.0
    run = aggregate([m])
    assert run["frames_gravity_none"] == 1 and "gravity_error_median_deg" not in run


def test_no_cuboids_no_shape_values():
    depth = np.full((CAM.height, CAM.width), 2.0, dtype=np.float32)
    m, s = shape_of(depth, [])
    assert s.visible_px.size == 0
    row = m.row()
    assert math.isnan(row["support_median_pct"]) and math.isnan(row["axis_angle_manhattan_median_deg"])


# ---------------------------------------------------------------- pooling


def _shape(angles_m, slab, support, err=math.nan, of="", room=None):
    n = len(angles_m)
    return ShapeMetrics(
        reference="synthetic",
        angle_gravity_deg=np.zeros(n),
        angle_manhattan_deg=np.array(angles_m, dtype=float),
        slab=np.array(slab, dtype=bool),
        room=np.array(slab if room is None else room, dtype=bool),
        visible_px=np.full(n, 100),
        supported_px=np.array(support),
        gravity_error_deg=err,
        gravity_error_of=of,
    )


def test_room_slabs_are_summarised_apart_from_other_slabs():
    # a: a wall at 0.5 degrees, a shelf at 2.9 (not the shell); b: a far wall at 3.1, a ceiling at 20
    a = _shape([0.5, 2.9, 10.0], [True, True, False], [100, 50, 0], room=[True, False, False])
    b = _shape([3.1, 20.0], [True, True], [90, 80], room=[True, True])
    s = shape_summary([a, b])
    assert s["slabs"] == 4 and s["slabs_within_3deg_pct"] == pytest.approx(50.0)
    assert s["room_slabs"] == 3 and s["room_slabs_within_3deg_pct"] == pytest.approx(100 / 3)


def test_room_slabs_of_a_rendered_room(nyu_camera):
    from cuboidcli.evaluation.shape import room_slabs
    from cuboidcli.synth import render_boxes
    from tests.conftest import simple_room

    room = simple_room()
    depth, _ = render_boxes(room, nyu_camera)
    # floor, back wall and left wall are the shell; the cabinet and the box are no slabs
    assert room_slabs(depth, nyu_camera, room).tolist() == [True, True, True, False, False]


def test_shape_and_gravity_summaries_pool_over_frames():
    a = _shape([0.5, 2.9, 10.0], [True, True, False], [100, 50, 0], err=1.0, of="estimated")
    b = _shape([3.1, 20.0], [True, True], [90, 80], err=3.0, of="fit")
    c = _shape([], [], [], err=math.nan, of="estimated")  # known gravity, no reliable estimate
    d = _shape([0.0], [True], [70])  # no known gravity
    s = shape_summary([a, b, c, d])
    assert s["slabs"] == 5 and s["slabs_within_3deg_pct"] == pytest.approx(100 * 3 / 5)
    assert s["axis_angle_manhattan_median_deg"] == pytest.approx(3.0)  # 0, .5, 2.9 | 3.1, 10, 20
    assert s["support_median_pct"] == pytest.approx(75.0) and s["support_mean_pct"] == pytest.approx(65.0)
    g = gravity_summary([a, b, c, d])
    assert g == {
        "gravity_error_median_deg": 2.0,
        "gravity_error_max_deg": 3.0,
        "gravity_within_2deg_pct": pytest.approx(100 / 3),
        "frames_with_known_gravity": 3,
        "gravity_estimates_missing": 1,
    }
    assert gravity_summary([d]) == {}


# ---------------------------------------------------------------- box recall at IoU 0.25


def test_box_recall_and_precision_at_iou_25(room):
    boxes, depth, _ = room
    exact = frame_metrics("f", depth, CAM, boxes, gt=boxes)
    assert exact.row()["box_recall_iou25_pct"] == 100.0 and exact.row()["box_precision_iou25_pct"] == 100.0
    far = Cuboid([0.0, 0.0, 30.0], [0.5, 0.5, 0.5], np.eye(3))
    cabinet = Cuboid(boxes[3].center, boxes[3].half_size * 0.7, boxes[3].rotation)  # IoU 0.343: a match
    small = Cuboid(boxes[4].center, boxes[4].half_size * 0.5, boxes[4].rotation)  # IoU 1/8: none
    pred = boxes[:3] + [cabinet, small, far]
    m = frame_metrics("f", depth, CAM, pred, gt=boxes)
    assert m.row()["box_recall_iou25_pct"] == pytest.approx(80.0)
    assert m.row()["box_precision_iou25_pct"] == pytest.approx(100 * 4 / 6)
    assert m.row()["recall_iou0.5_pct"] == pytest.approx(60.0)
    run = aggregate([exact, m])
    assert run["box_recall_iou25_pct"] == pytest.approx(100 * 9 / 10)
    assert run["box_precision_iou25_pct"] == pytest.approx(100 * 9 / 11)
    assert run["box_recall_iou25_pct"] == run["recall_iou0.25_pct"]
    assert "box_recall_iou25_pct" not in frame_metrics("f", depth, CAM, pred).row()  # no ground truth


# ---------------------------------------------------------------- datasets and the command


def synthetic_folder(root, pose=LEVEL_POSE) -> list[str]:
    """test_evaluate's folder with ground-truth files that carry the camera pose, as `cuboids synth`
    writes them (scene(i): a room box around the level camera and a box yawed by 15 i degrees)."""
    names = make_folder(root)
    for i, name in enumerate(names):
        extras = {"world_from_camera": pose.tolist(), "room": {}}
        write_result(root / "cuboids" / f"{name}.json", FitResult(SMALL_CAM, scene(i), extras=extras))
    return names


def test_known_gravity_is_read_from_synthetic_ground_truth_only(tmp_path):
    synthetic_folder(tmp_path / "synth")
    frames, _ = load_frames(tmp_path / "synth")
    np.testing.assert_allclose(frames[0].gt_world_from_camera(), LEVEL_POSE)
    make_folder(tmp_path / "plain")  # ground truth without a pose
    assert load_frames(tmp_path / "plain")[0][0].gt_world_from_camera() is None
    fit_like = tmp_path / "fitlike"
    make_folder(fit_like)  # a fit used as ground truth: its pose was estimated
    extras = {"world_from_camera": LEVEL_POSE.tolist(), "gravity": {"down": [0, 1, 0]}}
    write_result(fit_like / "cuboids" / "f0.json", FitResult(SMALL_CAM, scene(0), extras=extras))
    assert load_frames(fit_like)[0][0].gt_world_from_camera() is None


def test_saved_gravity_entries_are_read():
    g = gravity_from_saved(given_gravity([0.0, 2.0, 0.0]).to_dict())
    np.testing.assert_allclose(g.down, [0.0, 1.0, 0.0])
    assert g.frame is None
    assert gravity_from_saved(None) is None and gravity_from_saved({"down": [0, 0, 0]}) is None
    assert gravity_from_saved({"down": "x"}) is None


def test_cli_reports_shape_metrics_of_exact_fits_on_synthetic_frames(app, tmp_path):
    data, fits, out = tmp_path / "data", tmp_path / "fits", tmp_path / "out"
    synthetic_folder(data)
    for i in range(3):
        write_result(fits / f"f{i}.json", FitResult(SMALL_CAM, scene(i), timing_s={"total": 0.1}))
    # grid step 1: the 80x60 frames give a reliable gravity estimate only at full resolution
    res = CliRunner().invoke(
        app, ["evaluate", str(data), "--fits", str(fits), "--grid-step", "1", "-o", str(out)]
    )
    assert res.exit_code == 0, res.output
    assert "shape: medians over cuboids; axes of: synthetic 3" in res.output and "support %" in res.output
    assert "gravity error, depth estimate (3 frames)" in res.output
    doc = json.loads((out / "metrics.json").read_text())
    run = doc["runs"][0]
    assert run["frames_gravity_synthetic"] == 3 and run["frames_gravity_estimated"] == 0
    assert run["axis_angle_gravity_median_deg"] == 0.0
    assert run["axis_angle_manhattan_median_deg"] == 0.0  # 0, 0, 0, 0, 15, 30
    assert run["slabs"] == 0 and run["slabs_within_3deg_pct"] is None  # no slab in these scenes
    assert run["support_median_pct"] > 99.0
    assert run["frames_with_known_gravity"] == 3 and run["gravity_estimates_missing"] == 0
    assert run["gravity_error_max_deg"] < 0.1 and run["gravity_within_2deg_pct"] == 100.0
    assert run["box_recall_iou25_pct"] == 100.0 and run["box_precision_iou25_pct"] == 100.0
    assert doc["summary"]["support_median_pct"]["mean"] == run["support_median_pct"]
    per = doc["per_cuboid"]
    assert len(per) == 6 and per[3]["frame"] == "f1" and per[3]["cuboid"] == 1
    assert per[3]["axis_angle_manhattan_deg"] == pytest.approx(15.0) and per[3]["gravity_ref"] == "synthetic"
    assert per[5]["axis_angle_manhattan_deg"] == pytest.approx(30.0)
    with open(out / "frames.csv", newline="") as fh:
        rows = list(csv.DictReader(fh))
    assert rows[0]["gravity_ref"] == "synthetic" and float(
        rows[2]["axis_angle_manhattan_median_deg"]
    ) == pytest.approx(15.0)
    assert rows[0]["gravity_error_of"] == "estimated" and float(rows[0]["gravity_error_deg"]) < 0.1
    with open(out / "cuboids.csv", newline="") as fh:
        cub = list(csv.DictReader(fh))
    assert len(cub) == 6 and float(cub[5]["axis_angle_manhattan_deg"]) == pytest.approx(30.0)


def test_saved_fit_with_gravity_is_measured_against_it(app, tmp_path):
    data, fits, out = tmp_path / "data", tmp_path / "fits", tmp_path / "out"
    synthetic_folder(data)
    tilted = given_gravity(pitch(2.5) @ np.array([0.0, 1.0, 0.0]))
    for i in range(3):
        extras = {"gravity": tilted.to_dict()}
        write_result(
            fits / f"f{i}.json", FitResult(SMALL_CAM, scene(i), timing_s={"total": 0.1}, extras=extras)
        )
    res = CliRunner().invoke(app, ["evaluate", str(data), "--fits", str(fits), "-o", str(out)])
    assert res.exit_code == 0, res.output
    assert "gravity error, fit (3 frames)" in res.output
    run = json.loads((out / "metrics.json").read_text())["runs"][0]
    assert run["frames_gravity_fit"] == 3
    assert run["gravity_error_median_deg"] == pytest.approx(2.5, abs=1e-4)  # the file rounds to 6 decimals
    assert run["gravity_within_2deg_pct"] == 0.0
    assert run["axis_angle_gravity_median_deg"] == pytest.approx(2.5, abs=1e-4)
    assert run["axis_angle_manhattan_median_deg"] is None  # a given gravity has no room axes


def test_saved_fits_are_measured_with_their_grid_and_seed(app, tmp_path):
    """A fit without gravity, saved with grid step 1: the evaluation estimates gravity on the fit's grid
    (80x60 frames give a reliable estimate at grid step 1, none at the default 8)."""
    data, fits, out = tmp_path / "data", tmp_path / "fits", tmp_path / "out"
    make_folder(data)  # no known gravity
    for i in range(3):
        write_result(
            fits / f"f{i}.json", FitResult(SMALL_CAM, scene(i), settings={"grid_step": 1, "seed": 3})
        )
    res = CliRunner().invoke(app, ["evaluate", str(data), "--fits", str(fits), "-o", str(out)])
    assert res.exit_code == 0, res.output
    run = json.loads((out / "metrics.json").read_text())["runs"][0]
    assert run["frames_gravity_estimated"] == 3 and run["axis_angle_gravity_median_deg"] < 0.05


def test_align_option_fits_against_the_estimated_gravity(app, tmp_path):
    """--align gravity: the fit estimates gravity (grid step 1 at 80x60), its cuboids are upright against
    it, and the evaluation measures them against that gravity (reference "fit")."""
    data, out = tmp_path / "data", tmp_path / "out"
    synthetic_folder(data)
    opts = ["--hypotheses", "48", "--max-cuboids", "3", "--grid-step", "1", "--device", "cpu", "--limit", "2"]
    res = CliRunner().invoke(
        app, ["evaluate", str(data), *opts, "--align", "gravity", "-o", str(out), "--save-fits"]
    )
    assert res.exit_code == 0, res.output
    doc = json.loads((out / "metrics.json").read_text())
    assert doc["config"]["align"] == "gravity" and "gravity-aligned" in doc["method"]
    run = doc["runs"][0]
    assert run["frames_gravity_fit"] == 2
    assert run["gravity_error_max_deg"] < 0.5
    upright = 0
    for name in ("f0", "f1"):
        saved = json.loads((out / "fits" / "seed0" / f"{name}.json").read_text())
        angles = [c["axis_angle_gravity_deg"] for c in doc["per_cuboid"] if c["frame"] == name]
        for kind, angle in zip(saved["fit_info"]["aligned"], angles, strict=True):
            if kind == "gravity":  # upright against the fit's own up
                assert angle < 1e-6
                upright += 1
    assert upright >= 2
    res = CliRunner().invoke(app, ["evaluate", str(data), "--align", "sideways"])
    assert res.exit_code == 2 and "--align 'sideways': choose free, gravity, manhattan" in res.output


def test_frames_without_ground_truth_or_gravity_leave_the_fields_empty(tmp_path):
    """A generic folder without cuboids/: no box recall, no gravity error; the rest is measured."""
    root = tmp_path / "data"
    make_folder(root)
    for p in (root / "cuboids").iterdir():
        p.unlink()
    frames, _ = load_frames(root)
    report = evaluate(frames, FitConfig(hypotheses=32, max_cuboids=2, grid_step=2), EvalSettings())
    run = report.runs[0]
    assert "box_recall_iou25_pct" not in run and "frames_with_known_gravity" not in run
    assert run["frames_gravity_none"] == 3  # too few normals on the 40x30 fitting grid
    assert math.isfinite(run["support_median_pct"])
    for m in report.frames[0]:
        row = m.row()
        assert "gravity_error_deg" not in row and row["gravity_ref"] == "none"


def test_visible_faces_match_the_renderer_inside_and_outside_boxes():
    """The z-buffer follows each frame's own camera (an odd size, off-centre principal point); from inside
    a room box its far side is what the camera sees."""
    cam = Camera(fx=100.0, fy=90.0, cx=40.3, cy=20.7, width=77, height=45)
    room = Cuboid([0.2, -0.1, 1.5], [2.5, 1.5, 3.0], yaw(0.2))  # around the camera
    box = Cuboid([0.0, 0.0, 3.0], [0.5, 0.4, 0.3], np.eye(3))
    depth, inst = render_boxes([box, room], cam)
    owner, face = visible_faces(cam, [box, room])  # the far side of the room must not cover the box
    np.testing.assert_array_equal(owner, inst - 1)
    assert (owner == 1).sum() > 0.5 * owner.size
    np.testing.assert_allclose(face, depth, atol=1e-5)
    # rays parallel to a box's sides: with the principal point on a pixel centre, the rays of its column
    # and row have x = 0 (y = 0); a box beside that column and above that row must not be hit there
    cam = Camera(fx=50.0, fy=50.0, cx=20.0, cy=15.0, width=41, height=31)
    side = Cuboid([0.6, -0.6, 2.0], [0.3, 0.3, 0.3], np.eye(3))
    owner, _ = visible_faces(cam, [side])
    np.testing.assert_array_equal(owner, render_boxes([side], cam)[1] - 1)
    assert (owner[:, 20] == -1).all() and (owner[15, :] == -1).all() and (owner == 0).sum() > 50

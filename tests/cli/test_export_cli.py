"""``cuboids export`` through typer's CliRunner, on a tiny result, depth map and RGB image."""

from __future__ import annotations

import importlib.util
import sys
import types
from pathlib import Path

import cv2
import numpy as np
import pytest
import trimesh
import typer
from typer.testing import CliRunner

from cuboidcli.camera import Camera
from cuboidcli.cli.export import register
from cuboidcli.cuboid import Cuboid
from cuboidcli.export import raycast
from cuboidcli.io.result import FitResult, write_result

runner = CliRunner()
CAM = Camera(fx=60.0, fy=60.0, cx=31.5, cy=23.5, width=64, height=48)


def _scene() -> list[Cuboid]:
    turn = np.array([[0.8, 0.0, 0.6], [0.0, 1.0, 0.0], [-0.6, 0.0, 0.8]])
    return [
        Cuboid([-0.4, 0.1, 2.0], [0.25, 0.3, 0.2], turn),
        Cuboid([0.5, 0.2, 2.5], [0.3, 0.2, 0.3], np.eye(3)),
        Cuboid([0.1, -0.6, 1.8], [0.2, 0.15, 0.1], np.eye(3)),
    ]


@pytest.fixture
def app() -> typer.Typer:
    app = typer.Typer()
    app.callback()(lambda: None)  # keep `export` as a named subcommand
    register(app)
    return app


@pytest.fixture
def inputs(tmp_path):
    """result.json, a millimetre depth PNG and an RGB PNG of the same 64x48 scene."""
    cuboids = _scene()
    seen = raycast(CAM, cuboids[:2])
    depth = np.where(seen.label >= 0, seen.depth_m, 5.0)
    cv2.imwrite(str(tmp_path / "depth.png"), np.round(depth * 1000).astype(np.uint16))
    rgb = np.zeros((CAM.height, CAM.width, 3), np.uint8)
    rgb[..., 1] = 120
    cv2.imwrite(str(tmp_path / "rgb.png"), rgb)
    write_result(tmp_path / "result.json", FitResult(camera=CAM, cuboids=cuboids))
    return tmp_path


def test_export_all_formats(app, inputs):
    d = inputs
    res = runner.invoke(
        app,
        [
            "export",
            str(d / "result.json"),
            "--glb",
            str(d / "o.glb"),
            "--ply",
            str(d / "o.ply"),
            "--obj",
            str(d / "o.obj"),
            "--overlay",
            str(d / "o.png"),
            "--image",
            str(d / "rgb.png"),
            "--depth",
            str(d / "depth.png"),
            "--with-points",
        ],
    )
    assert res.exit_code == 0, res.output
    for name in (
        "o.glb",
        "o.ply",
        "o_cuboids.ply",
        "o.obj",
        "o.mtl",
        "o.png",
        "o_labels.png",
        "o_labels_color.png",
        "o_panel.png",
    ):
        assert (d / name).is_file(), name
        assert f"wrote {d / name}" in res.output.replace("\n", "")
    scene = trimesh.load(d / "o.glb")
    assert sorted(scene.graph.nodes_geometry) == ["object_00", "object_01", "object_02", "points"]
    assert len(trimesh.load(d / "o.ply").vertices) == CAM.width * CAM.height
    labels = cv2.imread(str(d / "o_labels.png"), cv2.IMREAD_UNCHANGED)
    assert np.array_equal(labels.astype(int) - 1, raycast(CAM, _scene()).label)
    overlay = cv2.imread(str(d / "o.png"))
    assert tuple(overlay[0, 0]) == (0, 120, 0)  # the RGB image shows where there is no cuboid


def test_overlay_without_rgb_uses_the_depth_map(app, inputs):
    d = inputs
    res = runner.invoke(
        app,
        [
            "export",
            str(d / "result.json"),
            "--overlay",
            str(d / "x_overlay.png"),
            "--depth",
            str(d / "depth.png"),
        ],
    )
    assert res.exit_code == 0, res.output
    assert (d / "x_panel.png").is_file() and (d / "x_labels.png").is_file()
    panel = cv2.imread(str(d / "x_panel.png"))
    assert panel.shape[1] == 3 * CAM.width + 2 * 4  # depth | cuboids | labels


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["export"], "nothing to export"),
        (["export", "--glb", "x.glb"], "pass RESULT.json"),
        (["export", "missing.json", "--glb", "x.glb"], "not found"),
        (["export", "{d}/result.json", "--ply", "{d}/x.ply"], "--depth"),
        (["export", "{d}/result.json", "--with-points", "--obj", "{d}/x.obj"], "--glb"),
        (["export", "{d}/result.json", "--overlay", "{d}/o.png", "--image", "{d}/nope.png"], "not found"),
        (["export", "{d}/result.json", "--weights", "w.pt", "--obj", "{d}/x.obj"], "--onnx"),
    ],
)
def test_export_errors_are_one_line(app, inputs, argv, message):
    res = runner.invoke(app, [a.format(d=inputs) for a in argv])
    assert res.exit_code == 2, res.output
    assert message in res.output and res.output.strip().count("\n") <= 1


def test_bad_result_json_is_a_clear_error(app, tmp_path):
    (tmp_path / "r.json").write_text('{"schema": "other"}')
    res = runner.invoke(app, ["export", str(tmp_path / "r.json"), "--glb", str(tmp_path / "x.glb")])
    assert res.exit_code == 2 and "not a cuboids/1 file" in res.output


def test_rgb_of_the_wrong_size_is_a_clear_error(app, inputs):
    cv2.imwrite(str(inputs / "small.png"), np.zeros((10, 12, 3), np.uint8))
    res = runner.invoke(
        app,
        [
            "export",
            str(inputs / "result.json"),
            "--overlay",
            str(inputs / "o.png"),
            "--image",
            str(inputs / "small.png"),
        ],
    )
    assert res.exit_code == 2 and "12x10" in res.output and "64x48" in res.output


def test_onnx_options_reach_the_solver_export(app, tmp_path, monkeypatch):
    calls = []

    def fake_export(weights_path, out_path, opset=17):
        calls.append((weights_path, out_path, opset))
        return Path(out_path)

    monkeypatch.setitem(
        sys.modules, "cuboidcli.solvers.onnx_export", types.SimpleNamespace(export_solver_onnx=fake_export)
    )
    (tmp_path / "w.pt").write_bytes(b"")
    res = runner.invoke(
        app,
        ["export", "--onnx", str(tmp_path / "s.onnx"), "--weights", str(tmp_path / "w.pt"), "--opset", "18"],
    )
    assert res.exit_code == 0, res.output
    assert calls == [(str(tmp_path / "w.pt"), str(tmp_path / "s.onnx"), 18)]
    assert "wrote" in res.output
    res = runner.invoke(
        app, ["export", "--onnx", str(tmp_path / "s.onnx"), "--weights", str(tmp_path / "no.pt")]
    )
    assert res.exit_code == 2 and "not found" in res.output


@pytest.mark.skipif(
    importlib.util.find_spec("cuboidcli.solvers.onnx_export") is None,
    reason="cuboidcli.solvers.onnx_export (the solver's ONNX export) is not in the tree yet",
)
def test_export_onnx(app, tmp_path):
    pytest.importorskip("onnx")
    import onnx
    import torch

    from cuboidcli.nets.checkpoint import checkpoint_dict
    from cuboidcli.nets.solver import SolverNet, SolverNetConfig

    torch.manual_seed(0)
    weights = tmp_path / "tiny.pt"
    torch.save(checkpoint_dict(SolverNet(SolverNetConfig(width=16, layers=1, heads=2, ff=32))), weights)
    res = runner.invoke(app, ["export", "--onnx", str(tmp_path / "solver.onnx"), "--weights", str(weights)])
    assert res.exit_code == 0, res.output
    model = onnx.load(str(tmp_path / "solver.onnx"))
    assert any(op.version == 17 for op in model.opset_import if op.domain in ("", "ai.onnx"))


def test_html_page_from_a_result_and_a_missing_extra_is_one_line(app, inputs, monkeypatch):
    """--html writes the viewer page (points from the depth map, boxes, table); without its library the
    command stops with one line naming the extra and writes nothing."""
    pytest.importorskip("plotly")
    d = inputs
    args = ["export", str(d / "result.json"), "--depth", str(d / "depth.png"), "--html", str(d / "v.html")]
    res = runner.invoke(app, args)
    assert res.exit_code == 0, res.output
    page = (d / "v.html").read_text()
    assert "plotly" in page.lower() and "<script src=" not in page and page.count("<tr") >= 4  # header + 3
    from cuboidcli import export

    monkeypatch.setitem(export.SCENE_EXTRAS, "html", ("no_such_plotting_library", "viz"))
    res = runner.invoke(app, [*args[:-1], str(d / "w.html")])
    assert res.exit_code == 2 and not (d / "w.html").exists()
    assert "--html needs the optional extra: pip install 'cuboids[viz]'" in " ".join(res.output.split())


def test_simulator_scenes_from_a_result_without_gravity_warn_and_load(app, inputs):
    mujoco = pytest.importorskip("mujoco")
    d = inputs
    res = runner.invoke(
        app, ["export", str(d / "result.json"), "--mjcf", str(d / "s.xml"), "--urdf", str(d / "s.urdf")]
    )
    assert res.exit_code == 0, res.output
    assert "warning: the result has no gravity" in " ".join(res.output.split())
    for name in ("s.xml", "s.urdf"):
        assert mujoco.MjModel.from_xml_path(str(d / name)).ngeom == 3


def test_usd_and_rerun_files_from_a_saved_result(app, inputs):
    pytest.importorskip("pxr")
    pytest.importorskip("rerun")
    from pxr import Usd, UsdGeom

    d = inputs
    res = runner.invoke(
        app,
        ["export", str(d / "result.json"), "--usd", str(d / "s.usdc"), "--rrd", str(d / "s.rrd"),
         "--depth", str(d / "depth.png"), "--image", str(d / "rgb.png")],
    )  # fmt: skip
    assert res.exit_code == 0, res.output
    stage = Usd.Stage.Open(str(d / "s.usdc"))
    assert len([p for p in stage.Traverse() if p.IsA(UsdGeom.Cube)]) == 3
    assert (d / "s.rrd").stat().st_size > 1000

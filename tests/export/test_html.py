"""The HTML viewer page: self-contained (no remote resource), and rendered by headless Chromium offline with
the boxes in their overlay colours."""

from __future__ import annotations

import re
import shutil
import subprocess
import sys
from dataclasses import replace
from pathlib import Path

import cv2
import numpy as np
import pytest

import cuboidcli as cb
from cuboidcli.cuboid import palette_color
from cuboidcli.export.html import MAX_VIEW_POINTS, figure, write_html

CHROMIUM = "/usr/bin/chromium"
needs_chromium = pytest.mark.skipif(shutil.which(CHROMIUM) is None, reason="chromium is not installed")
# the plot area of the 1200x900 screenshot (below the title, above the cuboid table)
PLOT_ROWS = slice(130, 740)


def chromium(page: Path, tmp: Path, *, screenshot: bool = True, size: str = "1200,900") -> np.ndarray | str:
    """Render ``page`` headless with every network request failing (a dead proxy, no name resolution):
    the screenshot as (H, W, 3) RGB, or with ``screenshot=False`` the DOM after the scripts ran."""
    profile = tmp / f"profile_{page.stem}"
    out = tmp / f"{page.stem}.png"
    cmd = [
        CHROMIUM,
        "--headless",
        "--no-sandbox",
        "--disable-gpu",
        "--disable-quic",
        "--no-first-run",
        "--disable-background-networking",
        "--disable-component-update",
        "--disable-sync",
        f"--user-data-dir={profile}",
        "--proxy-server=127.0.0.1:9",
        "--host-resolver-rules=MAP * ~NOTFOUND",
        f"--window-size={size}",
        "--virtual-time-budget=8000",
        f"--screenshot={out}" if screenshot else "--dump-dom",
        page.resolve().as_uri(),
    ]
    res = subprocess.run(cmd, capture_output=True, text=True, timeout=120)
    assert res.returncode == 0, res.stderr[-2000:]
    if not screenshot:
        return res.stdout
    img = cv2.imread(str(out), cv2.IMREAD_COLOR)
    assert img is not None, res.stderr[-2000:]
    return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)


def markup_outside_scripts(text: str) -> str:
    """The page without the bodies of its inline scripts (plotly.js names map-tile and licence addresses in
    its source; they are strings of the library that no 3D or 2D plot loads)."""
    return re.sub(r"(<script\b[^>]*>).*?(</script>)", r"\1\2", text, flags=re.S)


def assert_self_contained(text: str) -> None:
    assert "<script src=" not in text and not re.search(r"<script[^>]*\bsrc\s*=", text)
    markup = markup_outside_scripts(text)
    assert "cdn.plot.ly" not in markup.lower()
    for bad in ('src="http', "src='http", 'href="http', "href='http", "<link", "@import", "url(http"):
        assert bad not in markup, bad
    assert "Plotly.newPlot" in text and len(text) > 1_000_000  # plotly.js itself is inline


def plot_data(text: str) -> str:
    """The page's figure data: what follows its (last) Plotly.newPlot call, after the inline library."""
    return text[text.rindex("Plotly.newPlot(") :]


def colour_pixels(img: np.ndarray, rgb, tol: float = 12.0) -> int:
    return int((np.abs(img.astype(np.int32) - np.array(rgb)).max(axis=2) <= tol).sum())


@pytest.fixture(scope="module")
def fitted(room_depth, nyu_camera):
    depth, _ = room_depth
    return cb.fit(depth, nyu_camera, hypotheses=256, max_cuboids=4, device="cpu", seed=0, align="gravity")


def test_page_is_self_contained_with_points_boxes_panel_and_table(fitted, tmp_path):
    path = write_html(fitted, tmp_path / "scene.html")
    text = path.read_text(encoding="utf-8")
    assert_self_contained(text)
    assert markup_outside_scripts(text).count("data:image/png;base64,") == 1  # the overlay panel
    assert plot_data(text).count('"name":"points (') == 1
    fig = figure(fitted.record, depth_m=fitted.depth_m)
    meshes = [t for t in fig.data if t.type == "mesh3d"]
    assert len(meshes) == len(fitted.cuboids) and all(0 < m.opacity < 1 for m in meshes)
    assert [m.color for m in meshes] == [
        "rgb({},{},{})".format(*palette_color(k)) for k in range(len(meshes))
    ]
    points = fig.data[0]
    assert points.type == "scatter3d" and 10_000 < len(points.x) <= MAX_VIEW_POINTS
    for m in meshes:
        assert f'"name":"{m.name}"' in plot_data(text)
    table = text[text.index("<h2>Cuboids</h2>") :]
    assert table.count("<tr>") == len(fitted.cuboids) + 1
    for k, cub in enumerate(fitted.cuboids):
        assert "rgb({},{},{})".format(*palette_color(k)) in text
        assert f"{cub.inlier_gain:.1f}" in table
    assert not list(tmp_path.glob(".scene*"))  # the atomic write left no temporary file


def test_boxes_only_without_a_depth_map(fitted, tmp_path):
    text = write_html(fitted.record, tmp_path / "boxes.html").read_text(encoding="utf-8")
    assert '"name":"points (' not in plot_data(text) and "boxes only" in text
    fig = figure(fitted.record)
    assert sum(t.type == "mesh3d" for t in fig.data) == len(fitted.cuboids)


def test_mismatched_depth_map_is_refused(fitted, tmp_path):
    with pytest.raises(ValueError, match="depth map"):
        write_html(fitted.record, tmp_path / "x.html", depth_m=np.ones((10, 10)))


def test_missing_plotly_is_one_line(fitted, tmp_path, monkeypatch):
    monkeypatch.setitem(sys.modules, "plotly", None)
    monkeypatch.setitem(sys.modules, "plotly.graph_objects", None)
    with pytest.raises(ImportError) as err:
        write_html(fitted.record, tmp_path / "x.html")
    assert "\n" not in str(err.value) and "pip install 'cuboids[viz]'" in str(err.value)
    assert not (tmp_path / "x.html").exists()


@needs_chromium
def test_chromium_renders_the_boxes_in_their_colours_offline(fitted, tmp_path):
    boxes = chromium(write_html(fitted.record, tmp_path / "boxes.html"), tmp_path)[PLOT_ROWS]
    empty = replace(fitted.record, cuboids=[])
    none = chromium(write_html(empty, tmp_path / "none.html"), tmp_path)[PLOT_ROWS]
    for k in range(len(fitted.cuboids)):
        colour = palette_color(k)
        assert colour_pixels(boxes, colour) > 150, (k, colour, colour_pixels(boxes, colour))
        assert colour_pixels(none, colour) < 20, (k, colour)


@needs_chromium
def test_chromium_renders_the_point_cloud_page_not_blank(fitted, tmp_path):
    img = chromium(write_html(fitted, tmp_path / "scene.html"), tmp_path)
    plot = img[PLOT_ROWS]
    background = np.array([255, 255, 255])
    drawn = np.abs(plot.astype(np.int32) - background).max(axis=2) > 40
    assert drawn.mean() > 0.1, drawn.mean()  # the 3D scene (axes' grey background, points, boxes)
    # the points are coloured by cuboid: the first cuboid's colour fills a large area
    assert colour_pixels(plot, palette_color(0), tol=20) > 2000


def test_a_rooms_objects_are_drawn_by_kind(fitted):
    box = {"center": [0.0, 0.0, 2.0], "half_size": [0.2, 0.3, 0.4], "rotation": np.eye(3).tolist()}
    kinds = ["object", "door", "door", "sink", "shelf"]  # an unknown kind is drawn as furniture
    objects = [{**box, "kind": k} for k in kinds] + [dict(box)]  # and so is an object without one
    record = replace(fitted.record, extras={**fitted.record.extras, "objects": objects})
    traces = {t.name: t for t in figure(record).data if t.type == "scatter3d" and t.mode == "lines"}
    assert traces["objects (3)"].line.color == "black" and traces["doors (2)"].line.color == "saddlebrown"
    assert traces["sinks (1)"].line.color == "royalblue"
    assert all(t.line.dash == "dash" for t in traces.values() if "(" in t.name)
    assert len(traces["doors (2)"].x) == 2 * 12 * 3  # two boxes, 12 edges, two ends and a break each

"""A self-contained HTML page of a result: a 3D view of the points and boxes, the overlay panel, a table.

The page opens offline by double-click: plotly's JavaScript is embedded in it (no CDN, no remote script,
font or image) and the panel image is an inline base64 PNG. The 3D view is in the scene's world frame
(:mod:`cuboidcli.export.scene`: z up, levelled by gravity when the result has it); boxes are Mesh3d
triangles, semi-transparent, in the overlays' colours, with their edges drawn as lines and named like the
other exports (``wall_00``, ``object_03``...). plotly is an optional dependency (the ``viz`` extra) and is
imported only when a page is written.
"""

from __future__ import annotations

import base64
import html
import os
from pathlib import Path

import numpy as np

from cuboidcli.cuboid import palette_color
from cuboidcli.export.boxmesh import BOX_EDGES, BOX_TRIANGLES, CORNER_SIGNS
from cuboidcli.io.atomic import atomic_write_text

#: Points shown in the 3D view at most (the depth map is subsampled on a regular pixel grid).
MAX_VIEW_POINTS = 40_000
#: The embedded panel image is downscaled to at most this width (pixels).
MAX_PANEL_WIDTH = 1600
#: Opacity of the box faces in the 3D view.
FACE_OPACITY = 0.35
#: Colour of points that belong to no cuboid (points coloured by cuboid).
UNASSIGNED_RGB = (150, 150, 150)

VIZ_EXTRA_HINT = "pip install 'cuboids[viz]'"


def import_plotly():
    """``plotly.graph_objects``, or ImportError with one line naming the extra to install."""
    try:
        import plotly.graph_objects as go
    except ImportError:
        raise ImportError(f"the HTML page needs the optional extra: {VIZ_EXTRA_HINT}") from None
    return go


def _scene(result):
    """(world_from_camera (4, 4), has_gravity, [(name, center, half_size, rotation, rgb)]) in the world
    frame of :mod:`cuboidcli.export.scene`; rgb is the overlays' palette colour of each cuboid."""
    from cuboidcli.export.scene import world_boxes, world_from_camera

    pose, has_gravity = world_from_camera(result)
    boxes = [
        (name, np.asarray(c, float), np.asarray(h, float), np.asarray(r, float), palette_color(i))
        for i, (name, c, h, r, _rgba) in enumerate(world_boxes(result))
    ]
    return np.asarray(pose, dtype=np.float64), bool(has_gravity), boxes


def box_corners(center: np.ndarray, half_size: np.ndarray, rotation: np.ndarray) -> np.ndarray:
    """(8, 3) corners in the order of :data:`cuboidcli.export.boxmesh.CORNER_SIGNS`."""
    return center + (CORNER_SIGNS * half_size) @ rotation.T


def _rgb_css(rgb) -> str:
    return "rgb({},{},{})".format(*(int(v) for v in rgb))


def _view_points(result, depth_m: np.ndarray, rgb: np.ndarray | None, pose: np.ndarray):
    """World points (N, 3) subsampled to at most :data:`MAX_VIEW_POINTS`, and their colours (N, 3) uint8:
    the RGB image's, else the palette colour of the cuboid each point belongs to (grey: none)."""
    from cuboidcli.export.ply import assign_labels, depth_points

    cam = result.camera
    if depth_m.shape != (cam.height, cam.width):
        raise ValueError(
            f"the depth map is {depth_m.shape[1]}x{depth_m.shape[0]} but the result's camera is "
            f"{cam.width}x{cam.height}; pass the depth map the result was fitted on"
        )
    step = 1
    while -(-depth_m.shape[0] // step) * -(-depth_m.shape[1] // step) > MAX_VIEW_POINTS:
        step += 1
    points, pix = depth_points(depth_m, cam, step)
    if rgb is not None:
        if rgb.shape[:2] != depth_m.shape:
            raise ValueError("the RGB image and the depth map differ in size")
        colors = np.asarray(rgb, dtype=np.uint8).reshape(-1, 3)[pix]
    else:
        labels = assign_labels(points, result.cuboids, result.settings)
        table = np.array(
            [UNASSIGNED_RGB, *(palette_color(k) for k in range(len(result.cuboids)))], dtype=np.uint8
        )
        colors = table[np.where(labels >= 0, labels + 1, 0)]
    world = points @ pose[:3, :3].T + pose[:3, 3]
    return world, colors


def figure(
    result,
    *,
    depth_m: np.ndarray | None = None,
    rgb: np.ndarray | None = None,
    points: np.ndarray | None = None,
    point_colors: np.ndarray | None = None,
):
    """The plotly Figure of the 3D view: the points (of ``depth_m``, or a room's ``points`` (N, 3) in the
    result's frame with ``point_colors`` (N, 3) uint8) and one Mesh3d plus its edges per box, in the world
    frame; a frame's camera drawn as a small marker at its position."""
    go = import_plotly()
    pose, has_gravity, boxes = _scene(result)
    fig = go.Figure()
    pts = None
    if depth_m is not None:
        pts, cols = _view_points(result, np.asarray(depth_m, dtype=np.float64), rgb, pose)
    elif points is not None:
        step = max(1, -(-len(points) // MAX_VIEW_POINTS))
        pts = np.asarray(points, dtype=np.float64)[::step] @ pose[:3, :3].T + pose[:3, 3]
        cols = np.full((len(pts), 3), 160, np.uint8) if point_colors is None else point_colors[::step]
    if pts is not None:
        fig.add_trace(
            go.Scatter3d(
                x=pts[:, 0],
                y=pts[:, 1],
                z=pts[:, 2],
                mode="markers",
                name=f"points ({len(pts):,})",
                marker={"size": 1.5, "color": [_rgb_css(c) for c in cols]},
                hoverinfo="skip",
            )
        )
    tris = BOX_TRIANGLES
    for name, center, half, rot, color in boxes:
        corners = box_corners(center, half, rot)
        fig.add_trace(
            go.Mesh3d(
                x=corners[:, 0],
                y=corners[:, 1],
                z=corners[:, 2],
                i=tris[:, 0],
                j=tris[:, 1],
                k=tris[:, 2],
                color=_rgb_css(color),
                opacity=FACE_OPACITY,
                flatshading=True,
                name=name,
                legendgroup=name,
                showlegend=True,
                hovertemplate=f"{html.escape(name)}<extra></extra>",
            )
        )
        line = {"color": _rgb_css(color), "width": 5}
        fig.add_trace(edge_lines([corners], line, name=name, legendgroup=name, showlegend=False))
    _add_objects(fig, result, pose)
    if result.frame == "world":  # a room: no single camera; look from above one corner
        return _layout(fig, {"x": -1.2, "y": -1.2, "z": 1.0}, "world, z up (levelled: the room's up)")
    cam = pose[:3, 3]
    fig.add_trace(
        go.Scatter3d(
            x=[cam[0]],
            y=[cam[1]],
            z=[cam[2]],
            mode="markers",
            marker={"size": 4, "color": "black", "symbol": "diamond"},
            name="camera",
        )
    )
    fwd = pose[:3, 2].copy()  # the camera's viewing direction in the world frame
    fwd[2] = 0.0
    fwd = fwd / np.linalg.norm(fwd) if np.linalg.norm(fwd) > 1e-6 else np.array([0.0, 1.0, 0.0])
    eye = {"x": -1.6 * fwd[0], "y": -1.6 * fwd[1], "z": 0.9}  # behind and above the input camera
    frame = "world, z up (levelled by gravity)" if has_gravity else "world (no gravity: camera-aligned)"
    return _layout(fig, eye, frame)


def edge_lines(boxes: list[np.ndarray], line: dict, **trace):
    """One plotly line trace of the twelve edges of each box (corners (8, 3) in :func:`box_corners`'s
    order), separated by gaps; ``trace`` goes to the trace (name, legend group...)."""
    go = import_plotly()
    ex, ey, ez = [], [], []
    for corners in boxes:
        for a, b in BOX_EDGES:
            for axis, out in zip(range(3), (ex, ey, ez), strict=True):
                out += [corners[a, axis], corners[b, axis], None]
    return go.Scatter3d(x=ex, y=ey, z=ez, mode="lines", line=line, hoverinfo="skip", **trace)


#: How a room's objects of each kind (``objects[i].kind``) are drawn, and their legend entry's name.
OBJECT_STYLES = {
    "object": ("black", "objects"),
    "door": ("saddlebrown", "doors"),
    "sink": ("royalblue", "sinks"),
}


def _add_objects(fig, result, pose: np.ndarray) -> None:
    """A room's whole-object boxes (the JSON's ``objects``) as dashed edges, one legend entry for each kind
    (furniture black, doors brown, sinks blue) that shows or hides them all."""
    objects = result.extras.get("objects") or []
    by_kind: dict[str, list[np.ndarray]] = {}
    for o in objects:
        rot = pose[:3, :3] @ np.asarray(o["rotation"], dtype=np.float64)
        center = pose[:3, :3] @ np.asarray(o["center"], dtype=np.float64) + pose[:3, 3]
        kind = o.get("kind", "object") if o.get("kind") in OBJECT_STYLES else "object"
        by_kind.setdefault(kind, []).append(
            box_corners(center, np.asarray(o["half_size"], dtype=np.float64), rot)
        )
    for kind, (colour, name) in OBJECT_STYLES.items():
        if by_kind.get(kind):
            line = {"color": colour, "width": 3, "dash": "dash"}
            fig.add_trace(edge_lines(by_kind[kind], line, name=f"{name} ({len(by_kind[kind])})"))


def _layout(fig, eye: dict, frame: str):
    fig.update_layout(
        scene={
            "aspectmode": "data",
            "xaxis_title": "x (m)",
            "yaxis_title": "y (m)",
            "zaxis_title": "z (m)",
            "camera": {"up": {"x": 0, "y": 0, "z": 1}, "eye": eye},
        },
        margin={"l": 0, "r": 0, "t": 30, "b": 0},
        title={"text": frame, "font": {"size": 12}},
        legend={"itemsizing": "constant"},
        height=640,
    )
    return fig


def png_data_uri(image: np.ndarray, max_width: int = MAX_PANEL_WIDTH) -> str:
    """(H, W, 3) uint8 RGB -> ``data:image/png;base64,...``, downscaled to ``max_width`` pixels if wider."""
    import cv2

    img = np.asarray(image, dtype=np.uint8)
    if img.shape[1] > max_width:
        h = max(1, round(img.shape[0] * max_width / img.shape[1]))
        img = cv2.resize(img, (max_width, h), interpolation=cv2.INTER_AREA)
    ok, buf = cv2.imencode(".png", cv2.cvtColor(img, cv2.COLOR_RGB2BGR) if img.ndim == 3 else img)
    if not ok:
        raise OSError("could not encode the panel image as PNG")
    return "data:image/png;base64," + base64.b64encode(buf.tobytes()).decode("ascii")


def plot_div(fig, *, first: bool) -> str:
    """A figure as an HTML fragment; ``first`` embeds plotly's JavaScript (once per page), never a CDN."""
    return fig.to_html(
        include_plotlyjs=bool(first),
        full_html=False,
        config={"displaylogo": False, "responsive": True},
    )


PAGE_CSS = """
body{font-family:system-ui,-apple-system,"Segoe UI",Roboto,sans-serif;margin:16px 24px;color:#222}
h1{font-size:20px;margin:4px 0 8px} h2{font-size:16px;margin:20px 0 6px}
table{border-collapse:collapse;font-size:13px} td,th{border:1px solid #ccc;padding:3px 8px}
th{background:#f0f0f0;text-align:left} td.n{text-align:right;font-variant-numeric:tabular-nums}
.swatch{display:inline-block;width:12px;height:12px;border:1px solid #555;margin-right:6px;
vertical-align:middle} .muted{color:#777;font-size:12px} img.panel{max-width:100%;height:auto}
th.sortable{cursor:pointer} th.sortable:hover{background:#e2e2ff}
"""


def page(title: str, body: str) -> str:
    """A whole HTML document around ``body`` (no external resources)."""
    return (
        '<!DOCTYPE html>\n<html lang="en">\n<head>\n<meta charset="utf-8">\n'
        f"<title>{html.escape(title)}</title>\n<style>{PAGE_CSS}</style>\n</head>\n<body>\n"
        f"{body}\n</body>\n</html>\n"
    )


def _fmt(v, digits: int = 3) -> str:
    if v is None:
        return ""
    if isinstance(v, float):
        return "" if not np.isfinite(v) else f"{v:.{digits}f}"
    return html.escape(str(v))


def cuboid_table(result, boxes) -> str:
    """HTML table of the cuboids: name, kind, centre (world, m), size (full edge lengths, m), inlier gain."""
    rows = []
    for (name, center, half, _rot, color), cub in zip(boxes, result.cuboids, strict=True):
        kind = getattr(cub, "kind", None) or name.rsplit("_", 1)[0]
        centre = ", ".join(f"{v:.3f}" for v in center)
        size = " x ".join(f"{2 * v:.3f}" for v in half)
        rows.append(
            f'<tr><td><span class="swatch" style="background:{_rgb_css(color)}"></span>'
            f"{html.escape(name)}</td><td>{html.escape(str(kind))}</td><td class=n>{centre}</td>"
            f"<td class=n>{size}</td><td class=n>{_fmt(cub.inlier_gain, 1)}</td></tr>"
        )
    head = (
        "<tr><th>name</th><th>kind</th><th>centre x, y, z (m, world)</th><th>size (m)</th>"
        "<th>inlier gain</th></tr>"
    )
    return f"<table>\n{head}\n" + "\n".join(rows) + "\n</table>"


def html_page(
    result,
    *,
    depth_m: np.ndarray | None = None,
    rgb: np.ndarray | None = None,
    points: np.ndarray | None = None,
    point_colors: np.ndarray | None = None,
) -> str:
    """The viewer page as a string (see :func:`write_html`)."""
    from cuboidcli.export.overlay import render_images

    result = getattr(result, "record", result)  # an api.Result holds its FitResult as ``record``
    fig = figure(result, depth_m=depth_m, rgb=rgb, points=points, point_colors=point_colors)
    _pose, has_gravity, boxes = _scene(result)
    room = result.frame == "world"  # a room's result: no single camera, no image panel
    panel = None if room else render_images(result.camera, result.cuboids, rgb=rgb, depth_m=depth_m)["panel"]
    cam = result.camera
    total = result.timing_s.get("total") if isinstance(result.timing_s, dict) else None
    source = result.input.get("depth") or result.input.get("rgb") or result.input.get("path") or ""
    n_objects = len(result.extras.get("objects") or [])
    objects = f", {n_objects} object{'s' * (n_objects != 1)} (dashed)" if n_objects else ""
    info = [
        f"{len(result.cuboids)} cuboids{objects}",
        "a room, in its own frame" if room else f"camera {cam.width}x{cam.height}, fx {cam.fx:.1f}",
        "gravity: levelled, z up" if has_gravity else "no gravity estimate",
    ]
    if total is not None:
        info.append(f"fitted in {total:.2f} s")
    if source:
        info.append(f"input {html.escape(str(source))}")
    if depth_m is None and points is None:
        info.append("no depth map given: boxes only")
    from cuboidcli import __version__

    body = (
        f"<h1>cuboids: {len(result.cuboids)} boxes</h1>\n"
        f'<div class="muted">{" · ".join(info)} · cuboids {html.escape(__version__)}</div>\n'
        f"<h2>3D view</h2>\n{plot_div(fig, first=True)}\n"
        f"<h2>Cuboids</h2>\n{cuboid_table(result, boxes)}\n"
        '<p class="muted">centres in the world frame of the 3D view; sizes are full edge lengths along '
        "the box's own axes.</p>\n"
    )
    if panel is not None:
        body += f'<h2>Overlay</h2>\n<img class="panel" alt="overlay panel" src="{png_data_uri(panel)}">\n'
    return page("cuboids", body)


def write_html(
    result,
    path: str | os.PathLike,
    *,
    depth_m: np.ndarray | None = None,
    rgb: np.ndarray | None = None,
    points: np.ndarray | None = None,
    point_colors: np.ndarray | None = None,
) -> Path:
    """Write a self-contained HTML page of ``result`` (a FitResult, or an api.Result) to ``path``,
    atomically: the 3D view (points of ``depth_m`` (H, W) metres, subsampled to about
    :data:`MAX_VIEW_POINTS`, coloured from ``rgb`` (H, W, 3) uint8 or by cuboid; without ``depth_m`` the
    boxes only), the overlay panel and a table of the cuboids. Needs plotly (``cuboids[viz]``): ImportError
    with one line otherwise. ValueError for a depth map or image that does not match the result's camera."""
    if depth_m is None and hasattr(result, "record"):
        depth_m = result.depth_m
        rgb = result.rgb if rgb is None else rgb
    text = html_page(result, depth_m=depth_m, rgb=rgb, points=points, point_colors=point_colors)
    return atomic_write_text(path, text)

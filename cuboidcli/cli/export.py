"""``cuboids export``: convert a saved "cuboids/1" result to GLB / PLY / OBJ / PNG, or the solver to ONNX."""

from __future__ import annotations

from pathlib import Path

import typer

from cuboidcli.cli.common import console, fail, out, user_errors


def _input_file(result, key: str) -> Path | None:
    """The input file the result records under ``input[key]``, if it still exists."""
    value = result.input.get(key)
    return Path(value) if isinstance(value, str) and Path(value).is_file() else None


def _fitted_input_option(flag: str, what: str, used_for: str):
    """The option naming an input the result was fitted on (``what``, ``used_for`` these outputs); by
    default the file the result records."""
    return typer.Option(
        None,
        flag,
        help=f"{what} the result was fitted on ({used_for}); "
        "default: the one the result records, if it exists.",
    )


def export(
    result_json: Path | None = typer.Argument(
        None, metavar="RESULT.json", help="A cuboids/1 result written by `cuboids fit`.", show_default=False
    ),
    glb: Path | None = typer.Option(None, "--glb", help="Write the cuboids as GLB (Blender, three.js)."),
    ply: Path | None = typer.Option(
        None,
        "--ply",
        help="Write the point cloud coloured by cuboid to this PLY and the cuboid meshes to "
        "<name>_cuboids.ply (needs the depth map).",
    ),
    obj: Path | None = typer.Option(None, "--obj", help="Write the cuboids as OBJ (+ .mtl beside it)."),
    overlay: Path | None = typer.Option(
        None,
        "--overlay",
        help="Write the cuboids drawn over the image to this PNG, plus <name>_labels.png "
        "(0 = background, k+1 = cuboid k), <name>_labels_color.png and <name>_panel.png.",
    ),
    image: Path | None = _fitted_input_option(
        "--image", "RGB image", "overlay background, GLB point colours"
    ),
    depth: Path | None = _fitted_input_option(
        "--depth", "Depth map", "PLY, --with-points, overlay without RGB"
    ),
    depth_scale: float | None = typer.Option(
        None, "--depth-scale", help="Metres per depth-PNG unit; default: the result's, else 0.001."
    ),
    with_points: bool = typer.Option(False, "--with-points", help="Add the input point cloud to the GLB."),
    html: Path | None = typer.Option(
        None,
        "--html",
        help="Write a self-contained page that opens offline: a 3D view of the points and boxes, the overlay "
        "panel and a table of the cuboids (needs the viz extra).",
    ),
    mjcf: Path | None = typer.Option(
        None,
        "--mjcf",
        help="Write a MuJoCo scene (MJCF): a static box per cuboid, z up, the input camera (needs the sim "
        "extra).",
    ),
    urdf: Path | None = typer.Option(
        None, "--urdf", help="Write a URDF: a link per cuboid with box visual and collision, fixed to world."
    ),
    usd: Path | None = typer.Option(
        None,
        "--usd",
        help="Write a USD stage (.usda, .usdc or .usd; Isaac Sim, Blender, usdview): a Cube per cuboid, "
        "z up, metres, the input camera (needs the sim extra).",
    ),
    rrd: Path | None = typer.Option(
        None,
        "--rrd",
        help="Write a rerun recording: the image, depth, points, boxes and camera (needs the viz extra).",
    ),
    step: int = typer.Option(
        None,
        "--step",
        min=1,
        help="Use every step-th pixel for point clouds.",
        show_default="1, or what keeps a large frame's cloud within 640x480 points",
    ),
    onnx: Path | None = typer.Option(None, "--onnx", help="Export the neural solver to this ONNX file."),
    weights: Path | None = typer.Option(
        None, "--weights", help="Solver weights for --onnx (default: the packaged weights)."
    ),
    opset: int = typer.Option(17, "--opset", help="ONNX opset for --onnx."),
) -> None:
    """Convert a saved result to files other tools open, or export the neural solver to ONNX."""
    given = (
        ("glb", glb), ("ply", ply), ("obj", obj), ("overlay", overlay),
        ("html", html), ("mjcf", mjcf), ("urdf", urdf), ("usd", usd), ("rrd", rrd),
    )  # fmt: skip
    files = {kind: path for kind, path in given if path is not None}
    wants_files = bool(files)
    if onnx is None and not wants_files:
        fail(
            "nothing to export: pass --glb, --ply, --obj, --overlay, --html, --mjcf, --urdf, --usd or --rrd "
            "(with RESULT.json), or --onnx PATH"
        )
    if wants_files and result_json is None:
        fail("--glb/--ply/--obj/--overlay and the scene files convert a result: pass RESULT.json first")
    for kind in files:
        from cuboidcli.export import missing_extra

        message = missing_extra(kind)
        if message:
            fail(message)
    if weights is not None and onnx is None:
        fail("--weights only applies to --onnx PATH")
    if with_points and glb is None:
        fail("--with-points adds the points to the GLB: pass --glb PATH too")
    if onnx is not None:
        _export_onnx(onnx, weights, opset)
    if wants_files:
        _export_result(result_json, files, image, depth, depth_scale, with_points, step)


def _export_onnx(onnx: Path, weights: Path | None, opset: int) -> None:
    if weights is not None and not weights.exists():
        fail(f"--weights {weights}: not found")
    with user_errors():
        try:
            from cuboidcli.solvers.onnx_export import export_solver_onnx
            from cuboidcli.weights import default_path

            source = default_path("solver") if weights is None else weights
            path = export_solver_onnx(str(source), str(onnx), opset=opset)
        except ImportError as e:
            fail(
                f"ONNX export is unavailable ({e}); onnx and onnxruntime are dependencies of cuboids: "
                "pip install onnx onnxruntime"
            )
        except (ValueError, RuntimeError, OSError) as e:
            fail(f"ONNX export failed: {e}")
    out.print(f"wrote {path}", highlight=False)


def _export_result(result_json, files, image, depth, depth_scale, with_points, step) -> None:
    """Write ``files`` {output kind: main file} of the saved result ``result_json``: :func:`write` of its
    record with the depth map and image it was fitted on."""
    from cuboidcli.export import FittedData, unlevelled_warning, write
    from cuboidcli.io.depth import read_depth
    from cuboidcli.io.result import read_result

    with user_errors():
        try:
            result = read_result(result_json)
        except ValueError as e:
            fail(f"{result_json}: {e}; give a cuboids/1 result written by cuboids fit")
        warning = unlevelled_warning(result, files)
        if warning:
            console.print(f"[yellow]warning:[/] {warning}", highlight=False)
        depth = depth if depth is not None else _input_file(result, "depth")
        image = image if image is not None else _input_file(result, "image")
        if ("ply" in files or with_points) and depth is None:
            fail(
                "--ply and --with-points need the input points: pass --depth DEPTH (the map the result was "
                "fitted on)"
            )
        scale = depth_scale if depth_scale is not None else float(result.input.get("depth_scale") or 0.001)
        depth_m = None if depth is None else read_depth(depth, scale)
        rgb = None if image is None else _image(image, result.camera)
        try:
            fitted = FittedData.of_record(result, depth_m=depth_m, rgb=rgb)
            written = write(fitted, None, (), with_points=with_points, point_step=step, paths=files)
        except (ValueError, OSError, ImportError) as e:
            fail(str(e))
    for path in written.values():
        out.print(f"wrote {path}", highlight=False)


def _image(path, camera):
    """The image as the fit saw it: upright after its EXIF orientation, or as stored where that is the
    size of the result's camera (a depth map registered to the stored pixels)."""
    from cuboidcli.io.depth import read_rgb
    from cuboidcli.io.photo import read_photo

    rgb = read_photo(path).rgb
    if rgb.shape[:2] != (camera.height, camera.width):
        stored = read_rgb(path)
        if stored.shape[:2] == (camera.height, camera.width):
            return stored
    return rgb


def register(app: typer.Typer) -> None:
    """Add the ``export`` command to the ``cuboids`` app."""
    app.command("export")(export)

"""`cuboids fit`: its options, checked and turned into a job for the library, which fits a depth map or a
photo, a room (a scan, a sequence), or every input of a folder: a typed request
(:mod:`cuboidcli.cli.fit_request`) run by :mod:`cuboidcli.cli.fit_run`.
"""

from __future__ import annotations

from pathlib import Path

import typer

from cuboidcli.cli.common import fail, user_errors
from cuboidcli.cli.fit_request import FitRequest, Outputs, Run
from cuboidcli.cli.options import (
    DEFAULTS,
    config_option,
    device_option,
    fast_option,
    fit_config,
    shown_default,
)
from cuboidcli.cli.renamed import prefer_new, renamed_option, warn_renamed
from cuboidcli.cli.scale_options import (
    ray_address_option,
    ray_option,
    ray_target,
    skip_existing_option,
    workers_option,
)
from cuboidcli.load import LoadOptions
from cuboidcli.weights import DEFAULTS as WEIGHTS


def fit(
    ctx: typer.Context,
    image: Path = typer.Argument(
        None,
        help="RGB image (optional with --depth; used for overlays); without --depth an image or a folder of "
        "images, whose depth comes from a monocular network.",
    ),
    depth: Path = typer.Option(
        None,
        "--depth",
        "-d",
        help="Depth map (16-bit PNG, .npy/.npz in metres, .exr) or a folder of depth maps.",
    ),
    intrinsics: str = typer.Option(
        None,
        "--intrinsics",
        "-K",
        help="fx,fy,cx,cy in pixels (of the upright image), or a JSON file.",
        show_default="a preset, the photo's EXIF, the depth model, else a 63 degree field of view",
    ),
    camera: str = typer.Option(
        None,
        "--camera",
        help="Camera preset: nyu, tum or scannet (intrinsics + depth scale); scaled to an image of the same "
        "aspect ratio.",
    ),
    preset: str = renamed_option("--preset", "--camera"),
    depth_scale: float = typer.Option(
        None, "--depth-scale", help="Metres per depth-PNG unit.", show_default="0.001"
    ),
    output: Path = typer.Option(
        None,
        "--output",
        "-o",
        help="Output JSON, or an existing folder to write it into (for a folder of inputs: the folder of "
        "results).",
    ),
    hypotheses: int = config_option("hypotheses"),
    max_cuboids: int = config_option("max_cuboids", show_default=shown_default("max_cuboids")),
    sampler: str = config_option("sampler"),
    solver: str = config_option("solver"),
    weights: Path = typer.Option(
        None, "--weights", help="Folder with network weights.", show_default="shipped models/"
    ),
    onnx: Path = typer.Option(None, "--onnx", help="ONNX solver file for --solver onnx."),
    seed: int = config_option("seed"),
    device: str = device_option(),
    theta: float = config_option("theta", show_default=f"{DEFAULTS.theta_log_factor:g} ln n"),
    grid_step: int = config_option("grid_step", show_default="auto: about 4800 points"),
    occlusion_aware: bool = config_option("occlusion_aware"),
    fast: bool = fast_option(),
    refine: bool = config_option("refine"),
    local_fraction: float = config_option("local_fraction"),
    max_batches: int = config_option("max_batches"),
    align: str = config_option("align"),
    gravity_down: str = config_option(
        "gravity_down",
        show_default="estimated",
        more="Given as gx,gy,gz (any length) or 'level' (0,1,0); also levels the GLB.",
    ),
    slab_max_m: float = config_option("slab_max_m"),
    glb: bool = typer.Option(False, "--glb", help="Also write <out>.glb."),
    ply: bool = typer.Option(False, "--ply", help="Also write <out>_points.ply and <out>_cuboids.ply."),
    overlay: bool = typer.Option(False, "--overlay", help="Also write overlay, label and panel PNGs."),
    with_points: bool = typer.Option(False, "--with-points", help="Include the point cloud in the GLB."),
    html: bool = typer.Option(
        False, "--html", help="Also write <out>.html: a 3D view and table of the cuboids that opens offline."
    ),
    mjcf: bool = typer.Option(False, "--mjcf", help="Also write <out>_mjcf.xml, a MuJoCo scene (z up)."),
    urdf: bool = typer.Option(False, "--urdf", help="Also write <out>.urdf (a link per cuboid, z up)."),
    usd: bool = typer.Option(False, "--usd", help="Also write <out>.usda, a USD stage (z up, metres)."),
    rrd: bool = typer.Option(
        False,
        "--rrd",
        help="Also write a rerun recording: <out>.rrd, or for a folder one <folder>/cuboids.rrd with the "
        "frames on a 'frame' timeline.",
    ),
    rerun: bool = typer.Option(
        False, "--rerun", help="Stream each fitted frame to a running rerun viewer (start `rerun` first)."
    ),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Print only errors."),
    depth_model: str = typer.Option(
        None,
        "--depth-model",
        help="Without --depth: the monocular depth model: a Hugging Face model id (hf:owner/name, downloaded "
        "once into the Hugging Face cache; needs the hf extra) or a folder saved with save_pretrained, an "
        ".onnx file, or a .pt checkpoint of the built-in network.",
        show_default=f"models/{WEIGHTS['depth']}",
    ),
    depth_model_kind: str = typer.Option(
        None,
        "--depth-model-kind",
        help="metric | relative | relative-inverse: what the model predicts.",
        show_default="the model's own (its config, the ONNX preset; metric)",
    ),
    relative_scale: float = typer.Option(None, "--relative-scale", help="Scale for a relative depth model."),
    relative_shift: float = typer.Option(None, "--relative-shift", help="Shift for a relative depth model."),
    partial_depth: Path = typer.Option(
        None, "--partial-depth", help="Sparse/partial depth map to align a relative model to."
    ),
    camera_height: float = typer.Option(
        None,
        "--camera-height",
        help="The camera's height above the floor (m): scales a relative depth model so the floor lies that "
        "far below the camera.",
    ),
    onnx_preset: str = typer.Option(
        None,
        "--onnx-preset",
        help="Conventions of an ONNX depth model (docs/depth_models.md): depth-anything-v2, "
        "depth-anything-v2-metric, midas-v21-small, midas-v21, midas-dpt.",
    ),
    depth_edges: bool = typer.Option(
        False,
        "--drop-depth-edges/--keep-depth-edges",
        help="Leave out the points on discontinuities of depth estimated from RGB (smeared between objects; "
        "no gain measured with the built-in network).",
    ),
    unit: str = typer.Option("m", "--unit", help="A point cloud or mesh: its unit (m, cm or mm)."),
    every: int = typer.Option(1, "--every", help="A sequence folder: fuse every n-th frame."),
    visibility: str = config_option("visibility"),
    up: str = config_option(
        "up",
        show_default="estimated: the room's axis nearest the cameras' up, y for glTF, z otherwise",
        more="Given as z, y, -y, x or x,y,z.",
    ),
    voxel_m: float = config_option("voxel_m"),
    object_fits: int = config_option("object_fits"),
    workers: int = workers_option(),
    ray: bool = ray_option(),
    ray_address: str = ray_address_option(),
    skip_existing: bool = skip_existing_option(
        "A folder: skip frames whose outputs exist and were fitted with the same settings."
    ),
) -> None:
    """Fit cuboids to a depth map, a photo, a room scan or an RGB-D sequence and write "cuboids/1" JSON.

    With only an RGB image, depth comes from a monocular depth network (the built-in one by default).
    A point cloud or mesh (.ply, .pcd, .obj, .glb/.gltf, .npy/.npz of points) or a posed RGB-D sequence
    folder (TUM, ScanNet, Redwood, or depth/ + pose/ + cameras.json) is fitted as one room, in its own
    frame, with up to 60 cuboids."""
    # a command line refused for another reason gets that one line, not the deprecation warning too
    camera = prefer_new(camera, preset, "--preset", "--camera", warn=False)
    settings = dict(
        hypotheses=hypotheses, max_cuboids=max_cuboids, sampler=sampler, solver=solver, seed=seed,
        device=device, theta=theta, grid_step=grid_step, occlusion_aware=occlusion_aware, refine=refine,
        local_fraction=local_fraction, max_batches=max_batches, align=align, gravity_down=gravity_down,
        slab_max_m=slab_max_m, visibility=visibility, up=up, voxel_m=voxel_m, object_fits=object_fits,
    )  # fmt: skip
    depth_model_options = dict(
        model=depth_model, kind=depth_model_kind, scale=relative_scale, shift=relative_shift,
        partial_depth=None if partial_depth is None else str(partial_depth), camera_height_m=camera_height,
        onnx_preset=onnx_preset, drop_edges=depth_edges,
    )  # fmt: skip
    scenes = dict(html=html, mjcf=mjcf, urdf=urdf, usd=usd, rrd=rrd)
    kinds = tuple(k for k, on in dict(glb=glb, ply=ply, overlay=overlay, **scenes).items() if on)
    outputs = Outputs(output, kinds, with_points, rerun, quiet)
    run = Run(workers, ray_target(workers, ray, ray_address), skip_existing)
    request = fit_request(image, depth, settings, fast, depth_model_options, intrinsics, camera, depth_scale,
                          unit, every, weights, onnx, outputs, run, _typed_options(ctx))  # fmt: skip
    if preset is not None:
        warn_renamed("--preset", "--camera")
    from cuboidcli.cli.fit_run import run_request

    with user_errors():
        run_request(request)


def fit_request(
    image: Path | None,
    depth: Path | None,
    settings: dict,
    fast: bool,
    depth_model_options: dict,
    intrinsics: str | None,
    camera: str | None,
    depth_scale: float | None,
    unit: str,
    every: int,
    weights: Path | None,
    onnx: Path | None,
    outputs: Outputs,
    run: Run,
    typed: frozenset[str] = frozenset(),
) -> FitRequest:
    """The typed request of the options: what the input is, the settings given (checked, one line and exit 2
    for a bad value), how to read the input; an option that does not apply to it is refused."""
    from cuboidcli.factories import DepthModelOptions

    if depth is None and image is None:
        fail("give a depth map with --depth D.png or an RGB image (see cuboids fit --help)")
    model_kind = depth_model_options["kind"]
    if model_kind not in (None, "metric", "relative", "relative-inverse"):
        fail(f"--depth-model-kind {model_kind!r}: choose metric, relative or relative-inverse")
    # a setting is given when typed (even at its default value) or when it differs from its default
    given = {k: v for k, v in settings.items() if v is not None and (k in typed or v != getattr(DEFAULTS, k))}
    if isinstance(given.get("up"), str):
        from cuboidcli.io.depth import InputError
        from cuboidcli.load.room import parse_up

        try:
            given["up"] = parse_up(given["up"])
        except InputError as e:
            fail(str(e))
    config = fit_config({**given, "device": settings["device"], "fast": fast})
    for p, what in ((image, "image file"), (depth, "depth map")):
        if p is not None and not p.exists():
            fail(f"{what} not found: {p}")
    path, source, folder = _input(image, depth)
    model_given = any(v not in (None, False) for v in depth_model_options.values())
    model = None
    if source == "photo" or model_given:
        from cuboidcli.weights import depth_model_path

        opts = dict(depth_model_options, model=depth_model_path(depth_model_options["model"]))
        model = DepthModelOptions(**opts, device=config.device)
    load = LoadOptions(intrinsics, camera, depth_scale, unit, every, model)
    request = FitRequest(
        path, image if depth is not None else None, source, folder, config, frozenset(given), load, typed,
        None if weights is None else str(weights), None if onnx is None else str(onnx), outputs, run,
    )  # fmt: skip
    request.check()
    return request


def _typed_options(ctx) -> frozenset[str]:
    """The parameters of ``cuboids fit`` the user typed (or set through the environment), by name: what
    was typed must apply to the input even where it equals the default. Empty where the function is called
    without a command line (``cuboids demo``)."""
    if not hasattr(ctx, "get_parameter_source"):  # typer's context is its own copy of click's
        return frozenset()
    typed = ("COMMANDLINE", "ENVIRONMENT")
    return frozenset(
        name for name in ctx.params if getattr(ctx.get_parameter_source(name), "name", None) in typed
    )


def _input(image: Path | None, depth: Path | None) -> tuple[Path, str | None, bool]:
    """(the input, its source, whether it is a folder of such inputs)."""
    from cuboidcli.job import is_rooms_folder
    from cuboidcli.load.room import is_room_input

    if depth is not None:
        return depth, "depth", depth.is_dir()
    if is_room_input(image):
        return image, "sequence" if image.is_dir() else "scan", False
    if image.suffix.lower() in (".npy", ".npz"):  # an array is no photo: points, or a depth map
        fail(
            f"{image} holds no points ((N, 3) or (N, 6) with N > 6, or an .npz with 'points'); a depth map "
            f"is given with --depth {image}"
        )
    if image.is_dir():
        return (image, None, True) if is_rooms_folder(image) else (image, "photo", True)
    return image, "photo", False


def register(app: typer.Typer) -> None:
    app.command()(fit)

"""`cuboids fit`: its options, checked and turned into a job for the library, which fits a depth map or a
photo (:mod:`cuboidcli.cli.fit_frames`), every frame of a folder, or a room (:mod:`cuboidcli.cli.fit_scene`).
"""

from __future__ import annotations

from pathlib import Path

import typer

from cuboidcli.cli.common import fail, user_errors
from cuboidcli.cli.options import DEFAULTS, config_option, device_option, fast_option, fit_config
from cuboidcli.cli.renamed import prefer_new, renamed_option
from cuboidcli.cli.scale_options import (
    ray_address_option,
    ray_option,
    ray_target,
    skip_existing_option,
    workers_option,
)
from cuboidcli.fitting.scene import SceneConfig
from cuboidcli.weights import DEFAULTS as WEIGHTS


def fit(
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
        None, "--output", "-o", help="Output JSON (or folder for a folder of depth maps)."
    ),
    hypotheses: int = config_option("hypotheses"),
    max_cuboids: int = config_option("max_cuboids"),
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
    visibility: str = typer.Option(
        "auto",
        "--visibility",
        help="A room: how points count against a cuboid: views (no cuboid hides a point from its camera, "
        "nor holds the camera; a bare cloud is seen from just outside its surfaces), inside (no observed "
        "point inside a solid box), plain (plain inlier count); auto = views.",
    ),
    up: str = typer.Option(
        None,
        "--up",
        help="A room: its up direction in the input's frame: z, y, -y, x or x,y,z.",
        show_default="estimated: the room's axis nearest the cameras' up, y for glTF, z otherwise",
    ),
    voxel: float = typer.Option(
        None,
        "--voxel",
        help="A room: side of the voxels whose means are fitted (m).",
        show_default=str(SceneConfig.voxel_m),
    ),
    workers: int = workers_option(),
    ray: bool = ray_option(),
    ray_address: str = ray_address_option(),
    skip_existing: bool = skip_existing_option(
        "A folder: skip frames whose outputs exist and were fitted with the same settings."
    ),
) -> None:
    """Fit cuboids to a depth map (or every depth map in a folder) and write "cuboids/1" JSON.

    With only an RGB image, depth comes from a monocular depth network (the built-in one by default).
    A point cloud or mesh (.ply, .pcd, .obj, .glb/.gltf, .npy/.npz of points) or a posed RGB-D sequence
    folder (TUM, ScanNet, Redwood, or depth/ + pose/ + cameras.json) is fitted as one room, in its own
    frame, with up to 40 cuboids."""
    camera = prefer_new(camera, preset, "--preset", "--camera")
    options = dict(locals())  # the parameters named after FitConfig fields are its settings
    if image is not None and depth is None and image.exists() and _is_room_input(image):
        from cuboidcli.cli.fit_scene import fit_room_command

        fit_room_command(options)
        return
    if depth is None and image is None:
        fail("give a depth map with --depth D.png or an RGB image (see cuboids fit --help)")
    if depth_model_kind not in (None, "metric", "relative", "relative-inverse"):
        fail(f"--depth-model-kind {depth_model_kind!r}: choose metric, relative or relative-inverse")
    config = fit_config(options)
    if solver == "onnx" and onnx is None:
        fail("--solver onnx needs --onnx solver.onnx (make one with cuboids export --onnx)")
    if image is not None and not image.exists():
        fail(f"image file not found: {image}")
    if image is not None and image.is_dir():
        if depth is not None:
            fail("IMAGE is a folder: give it without --depth (depth from the images) or use --depth FOLDER")
        if partial_depth is not None:
            fail("--partial-depth belongs to one image; it cannot align every image of a folder")
    ray_at = ray_target(workers, ray, ray_address)
    folder_input = (depth is not None and depth.is_dir()) or (depth is None and image.is_dir())
    if (ray_at is not None or workers > 1) and not folder_input:
        fail("--workers and --ray fit the frames of a folder: give a folder of depth maps or images")
    from cuboidcli.cli import fit_frames

    with user_errors():
        job = fit_frames.frame_job(options, config)
        stream = fit_frames.rerun_stream() if rerun else None
        if folder_input:
            engine = fit_frames.Engine(workers, ray_at)
            fit_frames.fit_folder(job, depth or image, output, quiet, engine, skip_existing, stream)
            return
        res, written = fit_frames.fit_one(job, depth, image, output, quiet, stream)
    if not quiet:
        fit_frames.print_fit(res, written)


def _is_room_input(path: Path) -> bool:
    """A room (a scan file, a sequence folder) or a folder of rooms, which are fitted as rooms."""
    from cuboidcli.room_folder import is_rooms_folder
    from cuboidcli.scene import is_scene_input

    return is_scene_input(path) or is_rooms_folder(path)


def register(app: typer.Typer) -> None:
    app.command()(fit)

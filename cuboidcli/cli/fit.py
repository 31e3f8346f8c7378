"""`cuboids fit` and `cuboids demo`: parse options, build the config, call the library, print."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import typer
from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from cuboidcli.api import Fitter
from cuboidcli.cli.common import console, fail, out, user_errors
from cuboidcli.cli.options import (
    DEFAULTS,
    call_with_defaults,
    config_option,
    device_option,
    fast_option,
    fit_config,
)
from cuboidcli.cli.scale_options import (
    end_of_run,
    ray_address_option,
    ray_option,
    ray_target,
    run_with_progress,
    skip_existing_option,
    workers_option,
)
from cuboidcli.fitting.scene import SceneConfig
from cuboidcli.folder import FolderJob, fitter_for
from cuboidcli.weights import DEFAULTS as WEIGHTS

SAMPLE_DIR = Path(__file__).resolve().parents[1] / "data" / "sample"
DEPTH_SUFFIXES = (".png", ".npy", ".npz", ".exr")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


@dataclass
class FitJob:
    """Everything but the input files: how to read a frame, the estimator (built once), what to write."""

    intrinsics: str | None
    preset: str | None
    depth_scale: float | None
    fitter: Fitter
    glb: bool = False
    ply: bool = False
    overlay: bool = False
    with_points: bool = False
    depth_model: object = None
    scenes: tuple[str, ...] = ()

    def run(self, depth: Path | None, image: Path | None, progress=None):
        """Fit one frame; returns the api Result."""
        from cuboidcli.frame import load_frame

        frame = load_frame(
            depth, image, self.intrinsics, self.preset, self.depth_scale, depth_model=self.depth_model
        )
        for note in frame.notes:
            console.print(f"[yellow]warning:[/] {note}", highlight=False)
        if frame.meta["depth"] is None:
            console.print(f"[cyan]note:[/] {frame.meta['depth_source']}", highlight=False)
        result = self.fitter.fit_frame(frame, progress=progress)
        for note in result.info.warnings:
            console.print(f"[yellow]warning:[/] {note}", highlight=False)
        from cuboidcli.export import unlevelled_warning

        level = unlevelled_warning(result.record, self.scenes)
        if level:
            console.print(f"[yellow]warning:[/] {level}", highlight=False)
        return result

    def write(self, result, out_json: Path) -> list[Path]:
        return result.save(
            out_json,
            glb=self.glb,
            ply=self.ply,
            overlay=self.overlay,
            with_points=self.with_points,
            scenes=self.scenes,
        )

    def folder_job(self) -> FolderJob:
        """The picklable description of this job that worker processes and Ray tasks rebuild it from."""
        return FolderJob(
            config=self.fitter.config,
            weights=_str_or_none(self.fitter.weights),
            onnx=_str_or_none(self.fitter.onnx),
            intrinsics=self.intrinsics,
            preset=self.preset,
            depth_scale=self.depth_scale,
            depth_model=self.depth_model,
            glb=self.glb,
            ply=self.ply,
            overlay=self.overlay,
            with_points=self.with_points,
            scenes=self.scenes,
        )


def _check_extras(scenes: tuple[str, ...]) -> None:
    """Refuse, before any fitting, scene outputs whose optional library is missing (one line naming it)."""
    from cuboidcli.export import missing_extra

    for kind in scenes:
        message = missing_extra(kind)
        if message:
            fail(message)


def _depth_model_path(model: str | None, shipped_path) -> str | None:
    """A --depth-model value as the estimator takes it: a Hugging Face id as written, a file or folder
    resolved against the shipped models/."""
    if model is None or model.startswith("hf:"):
        return model
    return str(shipped_path(model))


def _str_or_none(p) -> str | None:
    return None if p is None else str(p)


def cuboid_table(result) -> Table:
    table = Table(title=f"{len(result.cuboids)} cuboids", title_justify="left")
    for col in ("#", "centre x, y, z (m)", "size x, y, z (m)", "inlier gain"):
        table.add_column(col, justify="right")
    for i, c in enumerate(result.cuboids):
        r, g, b = c.to_json(i)["color"]
        table.add_row(
            f"[rgb({r},{g},{b})]■[/] {i}",
            ", ".join(f"{v:6.2f}" for v in c.center),
            ", ".join(f"{2 * v:5.2f}" for v in c.half_size),
            f"{c.inlier_gain:.1f}",
        )
    return table


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
    preset: str = typer.Option(
        None,
        "--preset",
        help="Camera preset: nyu, tum or scannet (intrinsics + depth scale); scaled to an image of the same "
        "aspect ratio.",
    ),
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
    options = dict(locals())  # the parameters named after FitConfig fields are its settings
    if image is not None and depth is None and image.exists():
        from cuboidcli.scene import is_scene_input

        if is_scene_input(image) or _is_rooms_folder(image):
            _fit_room(options, ctx_max_cuboids=_given(options, "max_cuboids"))
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
    with user_errors():
        from cuboidcli.weights import check_weights_option, default_weights_dir, shipped_path

        check_weights_option(weights, config.solver, config.sampler)
        if weights is None:  # the shipped bundle that matches the input and the solver
            weights = default_weights_dir(config.solver, rgb=depth is None, builtin_depth=depth_model is None)
        try:
            # Built once per process and cached: a folder fitted in this process reuses it.
            fitter = fitter_for(config, _str_or_none(weights), _str_or_none(onnx))
        except (ValueError, FileNotFoundError, ImportError) as e:
            fail(str(e))
        wanted = (("html", html), ("mjcf", mjcf), ("urdf", urdf), ("usd", usd), ("rrd", rrd))
        scenes = tuple(kind for kind, on in wanted if on)
        _check_extras(scenes + (("rrd",) if rerun else ()))
        stream = _rerun_stream() if rerun else None
        if folder_input and "rrd" in scenes:  # one recording of the whole folder, written at the end
            scenes = tuple(k for k in scenes if k != "rrd")
            stream = _FolderRecording(stream)
        job = FitJob(intrinsics, preset, depth_scale, fitter, glb, ply, overlay, with_points, scenes=scenes)
        if depth is None:
            from cuboidcli.factories import DepthModelOptions

            job.depth_model = DepthModelOptions(
                _depth_model_path(depth_model, shipped_path),
                depth_model_kind,
                relative_scale,
                relative_shift,
                None if partial_depth is None else str(partial_depth),
                config.device,
                camera_height_m=camera_height,
                onnx_preset=onnx_preset,
                drop_edges=depth_edges,
            )
        if folder_input:
            engine = _Engine(workers, ray_at)
            _fit_folder(job, depth or image, output, quiet, depth is None, engine, skip_existing, stream)
            return
        with Progress(
            SpinnerColumn(),
            TextColumn("{task.description}"),
            TimeElapsedColumn(),
            console=console,
            transient=True,
            disable=quiet,
        ) as prog:
            task = prog.add_task("fitting: step 1", total=None)

            def step(it, n, gain):
                prog.update(task, description=f"fitting: step {it + 1}, {n} cuboids (last gain {gain:.0f})")

            res = job.run(depth, image, step)
        stem = (depth or image).stem
        written = job.write(res, output or Path(f"{stem}_cuboids.json"))
        if stream is not None:
            stream.log(res.record, res.depth_m, res.rgb)
    info = res.info
    if not quiet:
        out.print(cuboid_table(res))
        t = info.timing_s
        out.print(
            f"fitted {len(res.cuboids)} cuboids to {info.n_points} points in {t['total']:.2f} s "
            f"({'depth {:.2f} s, '.format(t['depth']) if 'depth' in t else ''}"
            f"solve {t['solve']:.2f} s, score {t['score']:.2f} s; stop: {info.stop_reason})"
        )
        for p in written:
            out.print(f"wrote {p}")


@dataclass(frozen=True)
class _Engine:
    """Where the frames of a folder run: ``workers`` local processes, or Ray (``ray`` "" = a local Ray,
    else the cluster's address; None = no Ray)."""

    workers: int = 1
    ray: str | None = None

    def describe(self) -> str:
        if self.ray is not None:
            return f"Ray at {self.ray}" if self.ray else "a local Ray"
        return f"{self.workers} processes" if self.workers > 1 else "this process"


def _fit_folder(
    job: FitJob,
    folder: Path,
    output: Path | None,
    quiet: bool,
    rgb: bool,
    engine: _Engine,
    skip_existing: bool,
    stream=None,
) -> None:
    """Fit every depth map (``rgb``: every colour image, depth estimated) of a folder, one JSON each, on
    ``engine``; frames whose outputs exist are skipped; ends with a summary, exit 1 if any frame failed."""
    from cuboidcli.folder import fit_file, is_complete
    from cuboidcli.scaleout import Outcome, Summary

    suffixes = IMAGE_SUFFIXES if rgb else DEPTH_SUFFIXES
    files = sorted(p for p in folder.iterdir() if p.suffix.lower() in suffixes and p.is_file())
    if rgb:
        # A folder of frames often holds the depth maps next to the photos (NYU, TUM): 16-bit or grey
        # images are not photos; they are left out with one line instead of one error each.
        photos = [f for f in files if _is_colour_image(f)]
        if len(photos) < len(files) and not quiet:
            console.print(
                f"[cyan]note:[/] left out {len(files) - len(photos)} files that are not colour images "
                "(depth maps?)",
                highlight=False,
            )
        files = photos
    if not files:
        kind = "colour images (*.png, *.jpg, ...)" if rgb else "depth maps (*.png, *.npy, *.npz, *.exr)"
        fail(f"no {kind} in {folder}")
    out_dir = output or Path(f"{folder.name}_cuboids")
    if out_dir.suffix == ".json":
        fail(f"-o must be a folder when {'IMAGE' if rgb else '--depth'} is a folder")
    if out_dir.exists() and not out_dir.is_dir():
        fail(f"-o {out_dir} is a file; give a folder")
    if job.intrinsics is None and (folder / "cameras.json").is_file():
        job.intrinsics = str(folder / "cameras.json")
    spec = job.folder_job()
    summary = Summary()
    todo: list[Path] = []
    for f in files:
        if skip_existing and is_complete(out_dir / f"{f.stem}_cuboids.json", spec):
            summary.add(Outcome(f.name, "skipped"))
        else:
            todo.append(f)
    if not quiet and summary.skipped:
        console.print(
            f"[cyan]note:[/] skipped {summary.skipped} frames whose outputs exist in {out_dir}/ "
            "(--no-skip-existing fits them again)",
            highlight=False,
        )
    tasks = [(spec, str(f), str(out_dir / f"{f.stem}_cuboids.json")) for f in todo]
    said_source = False

    def describe(i: int, res: Outcome) -> str:
        nonlocal said_source
        n, seconds, source = res.value
        if rgb and not said_source:
            console.print(f"[cyan]note:[/] {source}", highlight=False)
            said_source = True
        if stream is not None:
            stream.add(tasks[i][2])
        return f"{res.name}: {n} cuboids, {seconds:.2f} s"

    label = f"fitting on {engine.describe()}"
    run_with_progress(fit_file, tasks, [f.name for f in todo], engine, summary, quiet, label, describe)
    if isinstance(stream, _FolderRecording):
        path = stream.write(out_dir / "cuboids.rrd", [out_dir / f"{f.stem}_cuboids.json" for f in files])
        if not quiet:
            out.print(f"wrote {path}")
    end_of_run(summary, out_dir, quiet)


def _rerun_stream():
    """The running rerun viewer frames are streamed to (one line and exit 2 when none answers)."""
    from cuboidcli.export.rerun import RerunStream

    try:
        return RerunStream()
    except (ValueError, ImportError) as e:
        fail(str(e))


class _FolderRecording:
    """A folder's frames for one rerun recording: each finished frame's JSON is noted (and streamed to a
    viewer too with --rerun); the recording is written at the end, the frames in file order."""

    def __init__(self, stream=None) -> None:
        self.stream = stream

    def add(self, json_path: str) -> None:
        if self.stream is not None:
            self.stream.add(json_path)

    def write(self, path: Path, json_paths: list[Path]) -> Path:
        from cuboidcli.export.rerun import saved_inputs, write_rrd_frames
        from cuboidcli.io.result import read_result

        frames = []
        for p in json_paths:
            if p.is_file():
                result = read_result(p)
                frames.append((result, *saved_inputs(result)))
        return write_rrd_frames(frames, path)


def _given(options: dict, name: str):
    """The value of a FitConfig option when it differs from the frame's default, else None."""
    value = options.get(name)
    return None if value == getattr(DEFAULTS, name) else value


def _is_rooms_folder(path: Path) -> bool:
    """A folder of rooms (scan files, sequence sub-folders) and no images."""
    if not path.is_dir() or any(p.suffix.lower() in IMAGE_SUFFIXES for p in path.iterdir()):
        return False
    from cuboidcli.room_folder import rooms_in

    return bool(rooms_in(path))


def _fit_room(o: dict, ctx_max_cuboids: int | None) -> None:
    from cuboidcli.cli.fit_scene import fit_room, fit_rooms_folder, scene_config
    from cuboidcli.scene import is_scene_input

    folder = not is_scene_input(o["image"])
    ray_at = ray_target(o["workers"], o["ray"], o["ray_address"])
    if (o["workers"] > 1 or ray_at is not None) and not folder:
        fail("--workers and --ray fit the rooms of a folder; one room is fitted in one process")
    if o["sampler"] == "learned":
        fail("--sampler learned weighs the pixels of a depth map; a room is fitted with sequential")
    config = fit_config(o)
    scene = scene_config(ctx_max_cuboids, o["visibility"], o["up"], o["voxel"])
    wanted = (("html", o["html"]), ("mjcf", o["mjcf"]), ("urdf", o["urdf"]), ("usd", o["usd"]))
    scenes = tuple(kind for kind, on in wanted if on)
    with user_errors():
        _check_extras(scenes)
        try:
            fitter = fitter_for(config, _str_or_none(o["weights"]), _str_or_none(o["onnx"]))
        except (ValueError, FileNotFoundError, ImportError) as e:
            fail(str(e))
        if folder:
            from cuboidcli.room_folder import RoomJob

            job = RoomJob(
                config, scene, _str_or_none(o["weights"]), _str_or_none(o["onnx"]), o["unit"], o["every"],
                o["intrinsics"], o["depth_scale"], o["glb"], o["ply"], o["with_points"], scenes,
            )  # fmt: skip
            engine = _Engine(o["workers"], ray_at)
            fit_rooms_folder(job, o["image"], o["output"], o["quiet"], engine, o["skip_existing"])
            return
        outputs = {
            "glb": o["glb"], "ply": o["ply"], "overlay": o["overlay"], "with_points": o["with_points"],
            "scenes": scenes,
        }  # fmt: skip
        fit_room(
            fitter, o["image"], scene, o["output"], unit=o["unit"], every=o["every"],
            intrinsics=o["intrinsics"], depth_scale=o["depth_scale"], outputs=outputs, quiet=o["quiet"],
        )  # fmt: skip


def _is_colour_image(path: Path) -> bool:
    """Whether ``path`` is a colour image (3 or 4 channels); a one-channel PNG is taken for a depth map."""
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    return img is not None and img.ndim == 3 and img.shape[2] in (3, 4)


def demo(
    output: Path = typer.Option(Path("cuboids_demo"), "--output", "-o", help="Output folder."),
    seed: int = config_option("seed"),
    device: str = device_option(),
) -> None:
    """Fit the embedded sample scene (a synthetic room) and write JSON, GLB, PLY and overlay PNGs."""
    depth = SAMPLE_DIR / "sample_depth.png"
    if not depth.is_file():
        fail(f"the embedded sample is missing from {SAMPLE_DIR}; reinstall the package")
    call_with_defaults(  # cuboids fit with these options; the others are fit's defaults
        fit,
        image=SAMPLE_DIR / "sample.png",
        depth=depth,
        intrinsics=str(SAMPLE_DIR / "camera.json"),
        output=output / "sample_cuboids.json",
        seed=seed,
        device=device,
        glb=True,
        ply=True,
        overlay=True,
        with_points=True,
    )


def register(app: typer.Typer) -> None:
    app.command()(fit)
    app.command()(demo)

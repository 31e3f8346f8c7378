"""`cuboids fit` and `cuboids demo`: parse options, build the config, call the library, print."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import typer
from rich.progress import (
    BarColumn,
    MofNCompleteColumn,
    Progress,
    SpinnerColumn,
    TextColumn,
    TimeElapsedColumn,
)
from rich.table import Table

from cuboidcli.cli.common import console, fail, out, resolve_device, user_errors

SAMPLE_DIR = Path(__file__).resolve().parents[1] / "data" / "sample"
DEPTH_SUFFIXES = (".png", ".npy", ".npz", ".exr")
IMAGE_SUFFIXES = (".png", ".jpg", ".jpeg", ".bmp", ".tif", ".tiff", ".webp")


@dataclass
class FitJob:
    """Everything but the input files: how to read a frame, how to fit it, what to write."""

    intrinsics: str | None
    preset: str | None
    depth_scale: float | None
    config: object
    solver: object
    sampler: object
    weights: Path | None
    onnx: Path | None
    glb: bool = False
    ply: bool = False
    overlay: bool = False
    with_points: bool = False
    depth_model: object = None
    quiet_source: bool = False
    """Do not repeat the "depth estimated from RGB" note (every frame of a folder after the first)."""

    def run(self, depth: Path | None, image: Path | None, progress=None):
        """Fit one frame; returns (FitResult, FrameInput, FitInfo)."""
        from cuboidcli.fitting.frame import load_frame, make_result
        from cuboidcli.fitting.pipeline import fit_depth

        frame = load_frame(
            depth, image, self.intrinsics, self.preset, self.depth_scale, depth_model=self.depth_model
        )
        for note in frame.notes:
            console.print(f"[yellow]warning:[/] {note}", highlight=False)
        if frame.meta["depth"] is None and not self.quiet_source:
            console.print(f"[cyan]note:[/] {frame.meta['depth_source']}", highlight=False)
        cuboids, info = fit_depth(
            frame.depth_m,
            frame.camera,
            self.config,
            solver=self.solver,
            sampler=self.sampler,
            progress=progress,
        )
        if frame.depth_seconds is not None:
            info.add_depth_time(frame.depth_seconds)
        extra = {"weights": _str_or_none(self.weights), "onnx": _str_or_none(self.onnx)}
        res = make_result(
            frame.camera, cuboids, info, self.config, frame.meta, self.solver.name, self.sampler.name, extra
        )
        return res, frame, info

    def write(self, res, frame, out_json: Path) -> list[Path]:
        from cuboidcli.io.result import write_result

        written = [write_result(out_json, res)]
        if self.glb or self.ply or self.overlay:
            from cuboidcli.export import write_outputs

            stem = out_json.with_name(out_json.name.removesuffix(".json"))
            paths = write_outputs(
                res,
                stem,
                depth_m=frame.depth_m,
                rgb=frame.rgb,
                glb=self.glb,
                ply=self.ply,
                overlay=self.overlay,
                with_points=self.with_points,
            )
            written += list(paths.values())
        return written


def _str_or_none(p) -> str | None:
    return None if p is None else str(p)


def _config(
    hypotheses,
    max_cuboids,
    sampler,
    solver,
    seed,
    device,
    theta,
    grid_step,
    no_oai,
    fast,
    refine=True,
    local_fraction=None,
    max_batches=None,
):
    from cuboidcli.fitting.config import FitConfig

    defaults = FitConfig()
    if local_fraction is not None and not 0.0 <= local_fraction <= 1.0:
        fail(f"--local-fraction must be between 0 and 1 (got {local_fraction})")
    if max_batches is not None and max_batches < 1:
        fail(f"--max-batches must be at least 1 (got {max_batches})")
    if hypotheses < 1:
        fail(f"--hypotheses must be at least 1 (got {hypotheses})")
    if max_cuboids < 1:
        fail(f"--max-cuboids must be at least 1 (got {max_cuboids})")
    if grid_step < 1:
        fail(f"--grid-step must be at least 1 (got {grid_step})")
    if sampler not in ("uniform", "sequential", "local", "learned"):
        fail(f"--sampler {sampler!r}: choose sequential, local, uniform or learned")
    if solver not in ("numerical", "neural", "onnx"):
        fail(f"--solver {solver!r}: choose numerical, neural or onnx")
    return FitConfig(
        hypotheses=hypotheses,
        max_cuboids=max_cuboids,
        sampler=sampler,
        solver=solver,
        seed=seed,
        device=resolve_device(device),
        theta=theta,
        grid_step=grid_step,
        occlusion_aware=not no_oai,
        prescore_points=600 if fast else 0,
        refine=refine,
        local_fraction=defaults.local_fraction if local_fraction is None else local_fraction,
        max_batches=defaults.max_batches if max_batches is None else max_batches,
    )


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
    intrinsics: str = typer.Option(None, "--intrinsics", "-K", help="fx,fy,cx,cy in pixels, or a JSON file."),
    preset: str = typer.Option(
        None, "--preset", help="Camera preset: nyu, tum or scannet (intrinsics + depth scale)."
    ),
    depth_scale: float = typer.Option(
        None, "--depth-scale", help="Metres per depth-PNG unit [default: 0.001]."
    ),
    output: Path = typer.Option(
        None, "--output", "-o", help="Output JSON (or folder for a folder of depth maps)."
    ),
    hypotheses: int = typer.Option(
        3072, "--hypotheses", help="Cuboid hypotheses per step |H| (the paper: 4096)."
    ),
    max_cuboids: int = typer.Option(8, "--max-cuboids", help="At most this many cuboids."),
    sampler: str = typer.Option("sequential", "--sampler", help="sequential | learned | local | uniform."),
    solver: str = typer.Option("numerical", "--solver", help="numerical | neural | onnx."),
    weights: Path = typer.Option(
        None, "--weights", help="Folder with network weights [default: shipped models/]."
    ),
    onnx: Path = typer.Option(None, "--onnx", help="ONNX solver file for --solver onnx."),
    seed: int = typer.Option(0, "--seed", help="Random seed; the same seed gives the same cuboids."),
    device: str = typer.Option("auto", "--device", help="auto | cpu | cuda."),
    theta: float = typer.Option(None, "--theta", help="Minimum inlier gain per cuboid [default: 9 ln n]."),
    grid_step: int = typer.Option(8, "--grid-step", help="Fit on every n-th pixel (8 -> 60x80 at 480x640)."),
    no_oai: bool = typer.Option(
        False, "--no-oai", help="Plain inlier counting (the paper's no-OAI baselines)."
    ),
    fast: bool = typer.Option(
        False, "--fast", help="Approximate scoring: rank hypotheses on 600 points first."
    ),
    refine: bool = typer.Option(
        True, "--refine/--no-refine", help="Refine (and grow) each selected cuboid on its inliers."
    ),
    local_fraction: float = typer.Option(
        None,
        "--local-fraction",
        help="Share of minimal sets drawn from a 3D ball around their first point [default: 0.75]; "
        "0 = the paper's global sets.",
    ),
    max_batches: int = typer.Option(
        None,
        "--max-batches",
        help="Most batches of hypotheses per step when the best misses Theta [default: 4]; 1 = the paper.",
    ),
    glb: bool = typer.Option(False, "--glb", help="Also write <out>.glb."),
    ply: bool = typer.Option(False, "--ply", help="Also write <out>_points.ply and <out>_cuboids.ply."),
    overlay: bool = typer.Option(False, "--overlay", help="Also write overlay, label and panel PNGs."),
    with_points: bool = typer.Option(False, "--with-points", help="Include the point cloud in the GLB."),
    quiet: bool = typer.Option(False, "--quiet", "-q", help="Print only errors."),
    depth_model: str = typer.Option(
        None,
        "--depth-model",
        help="Without --depth: a user's monocular depth "
        "model (.onnx) or a built-in checkpoint (.pt) [default: models/depth_v3.pt].",
    ),
    depth_model_kind: str = typer.Option(
        "metric", "--depth-model-kind", help="metric | relative | relative-inverse (ONNX models)."
    ),
    relative_scale: float = typer.Option(None, "--relative-scale", help="Scale for a relative depth model."),
    relative_shift: float = typer.Option(None, "--relative-shift", help="Shift for a relative depth model."),
    partial_depth: Path = typer.Option(
        None, "--partial-depth", help="Sparse/partial depth map to align a relative model to."
    ),
) -> None:
    """Fit cuboids to a depth map (or every depth map in a folder) and write "cuboids/1" JSON.

    With only an RGB image, depth comes from a monocular depth network (the built-in one by default)."""
    if depth is None and image is None:
        fail("give a depth map with --depth D.png or an RGB image (see cuboids fit --help)")
    if depth_model_kind not in ("metric", "relative", "relative-inverse"):
        fail(f"--depth-model-kind {depth_model_kind!r}: choose metric, relative or relative-inverse")
    config = _config(
        hypotheses,
        max_cuboids,
        sampler,
        solver,
        seed,
        device,
        theta,
        grid_step,
        no_oai,
        fast,
        refine,
        local_fraction,
        max_batches,
    )
    if solver == "onnx" and onnx is None:
        fail("--solver onnx needs --onnx solver.onnx (make one with cuboids export --onnx)")
    if image is not None and not image.exists():
        fail(f"image file not found: {image}")
    if image is not None and image.is_dir():
        if depth is not None:
            fail("IMAGE is a folder: give it without --depth (depth from the images) or use --depth FOLDER")
        if partial_depth is not None:
            fail("--partial-depth belongs to one image; it cannot align every image of a folder")
    with user_errors():
        from cuboidcli.bundles import check_weights_option, default_weights_dir
        from cuboidcli.fitting.pipeline import ensure_compiled, make_solver
        from cuboidcli.fitting.sampling import make_sampler

        check_weights_option(weights, config.solver, config.sampler)
        if weights is None:  # the shipped bundle that matches the input and the solver
            weights = default_weights_dir(config.solver, rgb=depth is None, builtin_depth=depth_model is None)
        try:
            solver_obj = make_solver(config, weights, onnx, config.device)
            sampler_obj = make_sampler(config.sampler, weights, config.device)
        except (ValueError, FileNotFoundError, ImportError) as e:
            fail(str(e))
        if config.device == "cpu":
            ensure_compiled()
        job = FitJob(
            intrinsics,
            preset,
            depth_scale,
            config,
            solver_obj,
            sampler_obj,
            weights,
            onnx,
            glb,
            ply,
            overlay,
            with_points,
        )
        if depth is None:
            from cuboidcli.fitting.frame import DepthModelOptions

            job.depth_model = DepthModelOptions(
                depth_model,
                depth_model_kind,
                relative_scale,
                relative_shift,
                None if partial_depth is None else str(partial_depth),
                config.device,
            )
            if image.is_dir():
                _fit_folder(job, image, output, quiet, rgb=True)
                return
        elif depth.is_dir():
            _fit_folder(job, depth, output, quiet)
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

            res, frame, info = job.run(depth, image, step)
        stem = (depth or image).stem
        written = job.write(res, frame, output or Path(f"{stem}_cuboids.json"))
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


def _fit_folder(job: FitJob, folder: Path, output: Path | None, quiet: bool, rgb: bool = False) -> None:
    """Fit every depth map (``rgb``: every colour image, depth estimated) of a folder, one JSON each."""
    from cuboidcli.io.depth import InputError

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
    if job.intrinsics is None and (folder / "cameras.json").is_file():
        job.intrinsics = str(folder / "cameras.json")
    failures = 0
    with Progress(
        TextColumn("{task.description}"),
        BarColumn(),
        MofNCompleteColumn(),
        TimeElapsedColumn(),
        console=console,
        disable=quiet,
    ) as prog:
        task = prog.add_task("fitting", total=len(files))
        for i, f in enumerate(files):
            try:
                job.quiet_source = i > 0
                res, frame, info = job.run(None, f) if rgb else job.run(f, None)
                job.write(res, frame, out_dir / f"{f.stem}_cuboids.json")
                desc = f"{f.name}: {len(res.cuboids)} cuboids, {info.timing_s['total']:.2f} s"
            except InputError as e:
                failures += 1
                console.print(f"[red]skipped[/] {f.name}: {e}", highlight=False)
                desc = f"{f.name}: skipped"
            prog.update(task, advance=1, description=desc)
    if not quiet:
        out.print(f"wrote {len(files) - failures} results to {out_dir}/")
    if failures:
        raise typer.Exit(1)


def _is_colour_image(path: Path) -> bool:
    """Whether ``path`` is a colour image (3 or 4 channels); a one-channel PNG is taken for a depth map."""
    import cv2

    img = cv2.imread(str(path), cv2.IMREAD_UNCHANGED)
    return img is not None and img.ndim == 3 and img.shape[2] in (3, 4)


def demo(
    output: Path = typer.Option(Path("cuboids_demo"), "--output", "-o", help="Output folder."),
    seed: int = typer.Option(0, "--seed"),
    device: str = typer.Option("auto", "--device", help="auto | cpu | cuda."),
) -> None:
    """Fit the embedded sample scene (a synthetic room) and write JSON, GLB, PLY and overlay PNGs."""
    depth = SAMPLE_DIR / "sample_depth.png"
    if not depth.is_file():
        fail(f"the embedded sample is missing from {SAMPLE_DIR}; reinstall the package")
    fit(
        image=SAMPLE_DIR / "sample.png",
        depth=depth,
        intrinsics=str(SAMPLE_DIR / "camera.json"),
        preset=None,
        depth_scale=None,
        output=output / "sample_cuboids.json",
        hypotheses=3072,
        max_cuboids=8,
        sampler="sequential",
        solver="numerical",
        weights=None,
        onnx=None,
        seed=seed,
        device=device,
        theta=None,
        grid_step=8,
        no_oai=False,
        fast=False,
        refine=True,
        local_fraction=None,
        max_batches=None,
        glb=True,
        ply=True,
        overlay=True,
        with_points=True,
        quiet=False,
        depth_model=None,
        depth_model_kind="metric",
        relative_scale=None,
        relative_shift=None,
        partial_depth=None,
    )


def register(app: typer.Typer) -> None:
    app.command()(fit)
    app.command()(demo)

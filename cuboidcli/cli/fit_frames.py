"""`cuboids fit` for depth maps and photos: the :class:`~cuboidcli.folder.FrameJob` of the command's options,
run for one frame or for each frame of a folder, and what is printed about it."""

from __future__ import annotations

from dataclasses import dataclass, replace
from pathlib import Path

from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from cuboidcli.cli.common import console, fail, out
from cuboidcli.cli.scale_options import end_of_run, run_with_progress
from cuboidcli.folder import FolderRecording, FrameJob


@dataclass(frozen=True)
class Engine:
    """Where the frames of a folder run: ``workers`` local processes, or Ray (``ray`` "" = a local Ray,
    else the cluster's address; None = no Ray)."""

    workers: int = 1
    ray: str | None = None

    def describe(self) -> str:
        if self.ray is not None:
            return f"Ray at {self.ray}" if self.ray else "a local Ray"
        return f"{self.workers} processes" if self.workers > 1 else "this process"


def check_extras(scenes: tuple[str, ...]) -> None:
    """Refuse, before any fitting, scene outputs whose optional library is missing (one line naming it)."""
    from cuboidcli.export import missing_extra

    for kind in scenes:
        message = missing_extra(kind)
        if message:
            fail(message)


def scene_kinds(o: dict, kinds: tuple[str, ...] | None = None) -> tuple[str, ...]:
    """The scene files the options ask for (``--html``, ``--mjcf``, ...), in the order of ``kinds`` (None:
    every kind of :data:`cuboidcli.export.files.SCENES`)."""
    from cuboidcli.export.files import SCENES

    return tuple(kind for kind in (tuple(SCENES) if kinds is None else kinds) if o[kind])


def _str_or_none(p) -> str | None:
    return None if p is None else str(p)


def frame_job(o: dict, config) -> FrameJob:
    """The job of the command's options ``o`` and FitConfig ``config``: the weights that go with the input
    and the solver, the estimator built (one line and exit 2 when it cannot be), the scene kinds checked
    and, without ``--depth``, the depth model. Call inside :func:`~cuboidcli.cli.common.user_errors`."""
    from cuboidcli.weights import check_weights_option, default_weights_dir

    weights, rgb = o["weights"], o["depth"] is None
    check_weights_option(weights, config.solver, config.sampler)
    if weights is None:  # the shipped bundle that matches the input and the solver
        weights = default_weights_dir(config.solver, rgb=rgb, builtin_depth=o["depth_model"] is None)
    job = FrameJob(config, _str_or_none(weights), _str_or_none(o["onnx"]), o["intrinsics"], o["camera"])
    try:
        job.fitter()  # built once per process and cached: each frame of a folder fitted here reuses it
    except (ValueError, FileNotFoundError, ImportError) as e:
        fail(str(e))
    scenes = scene_kinds(o)
    check_extras(scenes + (("rrd",) if o["rerun"] else ()))
    outputs = {k: o[k] for k in ("depth_scale", "glb", "ply", "overlay", "with_points")}
    job = replace(job, scenes=scenes, **outputs)
    if not rgb:
        return job
    from cuboidcli.factories import DepthModelOptions
    from cuboidcli.weights import depth_model_path

    return replace(
        job,
        depth_model=DepthModelOptions(
            depth_model_path(o["depth_model"]),
            o["depth_model_kind"],
            o["relative_scale"],
            o["relative_shift"],
            _str_or_none(o["partial_depth"]),
            config.device,
            camera_height_m=o["camera_height"],
            onnx_preset=o["onnx_preset"],
            drop_edges=o["depth_edges"],
        ),
    )


def rerun_stream():
    """The running rerun viewer frames are streamed to (one line and exit 2 when none answers)."""
    from cuboidcli.export.rerun import RerunStream

    try:
        return RerunStream()
    except (ValueError, ImportError) as e:
        fail(str(e))


def _note(text: str, kind: str = "[yellow]warning:[/]") -> None:
    console.print(f"{kind} {text}", highlight=False)


def fit_one(job: FrameJob, depth: Path | None, image: Path | None, output: Path | None, quiet: bool, stream):
    """Fit one frame with a spinner, write its outputs (``output`` or ``<stem>_cuboids.json``), stream it
    to the viewer; returns (result, paths written)."""
    from cuboidcli.export import unlevelled_warning
    from cuboidcli.export.files import result_name

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

        frame = job.load(depth or image, image)
        for note in frame.notes:
            _note(note)
        if frame.meta["depth"] is None:
            _note(frame.meta["depth_source"], "[cyan]note:[/]")
        res = job.fit(frame, progress=step)
        for note in res.info.warnings:
            _note(note)
        level = unlevelled_warning(res.record, job.scenes)
        if level:
            _note(level)
    written = job.save(res, output or Path(result_name(depth or image)))
    if stream is not None:
        stream.log(res.record, res.depth_m, res.rgb)
    return res, written


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


def print_fit(res, written: list[Path]) -> None:
    """The cuboids, the fit in one line and the files written."""
    info = res.info
    out.print(cuboid_table(res))
    t = info.timing_s
    out.print(
        f"fitted {len(res.cuboids)} cuboids to {info.n_points} points in {t['total']:.2f} s "
        f"({'depth {:.2f} s, '.format(t['depth']) if 'depth' in t else ''}"
        f"solve {t['solve']:.2f} s, score {t['score']:.2f} s; stop: {info.stop_reason})"
    )
    for p in written:
        out.print(f"wrote {p}")


def fit_folder(
    job: FrameJob,
    folder: Path,
    output: Path | None,
    quiet: bool,
    engine: Engine,
    skip_existing: bool,
    stream=None,
) -> None:
    """Fit every depth map (a job from RGB: every colour image, depth estimated) of a folder, one JSON each,
    on ``engine``; frames whose outputs exist are skipped; ends with a summary, exit 1 if any frame failed.
    With ``rrd`` among the job's scenes the folder gets one recording of all its frames."""
    from cuboidcli.export.files import FOLDER_RECORDING, result_name, results_folder
    from cuboidcli.folder import fit_file, folder_tasks
    from cuboidcli.io.inputs import depth_maps_in, photos_in
    from cuboidcli.scaleout import Outcome, Summary

    rgb = job.from_rgb
    if rgb:
        files, left_out = photos_in(folder)
        if left_out and not quiet:
            _note(f"left out {left_out} files that are not colour images (depth maps?)", "[cyan]note:[/]")
    else:
        files = depth_maps_in(folder)
    if not files:
        kind = "colour images (*.png, *.jpg, ...)" if rgb else "depth maps (*.png, *.npy, *.npz, *.exr)"
        fail(f"no {kind} in {folder}")
    out_dir = output or results_folder(folder)
    if out_dir.suffix == ".json":
        fail(f"-o must be a folder when {'IMAGE' if rgb else '--depth'} is a folder")
    if out_dir.exists() and not out_dir.is_dir():
        fail(f"-o {out_dir} is a file; give a folder")
    if "rrd" in job.scenes:  # one recording of the whole folder, written at the end
        job = replace(job, scenes=tuple(k for k in job.scenes if k != "rrd"))
        stream = FolderRecording(stream)
    tasks, skipped = folder_tasks(job.in_folder(folder), files, out_dir, skip_existing)
    summary = Summary()
    for f in skipped:
        summary.add(Outcome(f.name, "skipped"))
    if not quiet and summary.skipped:
        _note(
            f"skipped {summary.skipped} frames whose outputs exist in {out_dir}/ (--no-skip-existing fits "
            "them again)",
            "[cyan]note:[/]",
        )
    said_source = False

    def describe(i: int, res: Outcome) -> str:
        nonlocal said_source
        n, seconds, source = res.value
        if rgb and not said_source:
            _note(source, "[cyan]note:[/]")
            said_source = True
        if stream is not None:
            stream.add(tasks[i][2])
        return f"{res.name}: {n} cuboids, {seconds:.2f} s"

    label = f"fitting on {engine.describe()}"
    names = [Path(t[1]).name for t in tasks]
    run_with_progress(fit_file, tasks, names, engine, summary, quiet, label, describe)
    if isinstance(stream, FolderRecording):
        path = stream.write(out_dir / FOLDER_RECORDING, [out_dir / result_name(f) for f in files])
        if not quiet:
            out.print(f"wrote {path}")
    end_of_run(summary, out_dir, quiet)

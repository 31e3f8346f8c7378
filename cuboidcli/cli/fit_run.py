"""``cuboids fit`` run: the :class:`~cuboidcli.job.Job` of a :class:`~cuboidcli.cli.fit_request.FitRequest`,
for one input (a frame or a room, with a progress display) or for each input of a folder (on this
process, ``--workers`` processes or Ray, resumably), and what is printed about it."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from rich.progress import Progress, SpinnerColumn, TextColumn, TimeElapsedColumn
from rich.table import Table

from cuboidcli.cli.common import check_writable, console, fail, out
from cuboidcli.cli.fit_request import FitRequest
from cuboidcli.cli.scale_options import end_of_run, run_with_progress
from cuboidcli.job import FolderRecording, Job
from cuboidcli.result import objects_summary


def check_extras(kinds: tuple[str, ...]) -> None:
    """Refuse, before any fitting, outputs whose optional library is missing (one line naming it)."""
    from cuboidcli.export import missing_extra

    for kind in kinds:
        message = missing_extra(kind)
        if message:
            fail(message)


def job_of(request: FitRequest) -> Job:
    """The job of a request: the weights that go with the input and the solver, the estimator built (one
    line and exit 2 when it cannot be), the outputs' extras checked."""
    from cuboidcli.weights import check_weights_option, default_weights_dir

    config, weights = request.config, request.weights
    check_weights_option(weights, config.solver, config.sampler)
    if weights is None:  # the shipped bundle that matches the input and the solver
        model = request.load.depth_model
        builtin = model is None or model.model is None
        found = default_weights_dir(config.solver, rgb=request.source == "photo", builtin_depth=builtin)
        weights = None if found is None else str(found)
    kinds = request.outputs.kinds
    job = Job(config, weights, request.onnx, request.load, request.source, kinds, request.outputs.with_points)
    if request.folder:  # built once per process and cached, so bad weights fail before any input is listed
        try:
            job.fitter()
        except (ValueError, FileNotFoundError, ImportError) as e:
            fail(str(e))
    check_extras(
        tuple(k for k in kinds if k not in ("glb", "ply", "overlay"))
        + (("rrd",) if request.outputs.rerun else ())
    )
    return job


def run_request(request: FitRequest) -> None:
    """Fit what the request asks for and print it (call inside :func:`~cuboidcli.cli.common.user_errors`)."""
    job = job_of(request)
    stream = rerun_stream() if request.outputs.rerun else None
    if request.folder:
        fit_folder(job, request, stream)
        return
    res, written = fit_one(job, request, stream)
    if not request.outputs.quiet:
        print_fit(res, written)


def rerun_stream():
    """The running rerun viewer results are streamed to (one line and exit 2 when none answers)."""
    from cuboidcli.export.rerun import RerunStream

    try:
        return RerunStream()
    except (ValueError, ImportError) as e:
        fail(str(e))


def _note(text: str, kind: str = "[yellow]warning:[/]") -> None:
    console.print(f"{kind} {text}", highlight=False)


def fit_one(job: Job, request: FitRequest, stream):
    """Read, fit and write one input behind a progress display (a sequence's fusion, the fitting steps);
    returns (result, paths written)."""
    from cuboidcli.export import unlevelled_warning
    from cuboidcli.export.files import result_name

    quiet = request.outputs.quiet
    out_json = request.outputs.output or Path(result_name(request.path))
    if out_json.is_dir():  # an existing folder: the result goes into it
        out_json = out_json / ("cuboids.json" if request.kind == "room" else result_name(request.path))
    elif out_json.suffix.lower() != ".json":
        out_json = out_json.with_suffix(".json")
    check_writable(out_json.parent)
    with Progress(
        SpinnerColumn(), TextColumn("{task.description}"), TimeElapsedColumn(), console=console,
        transient=True, disable=quiet,
    ) as prog:  # fmt: skip
        task = prog.add_task("reading", total=None)

        def fused(done: int, total: int) -> None:
            prog.update(task, description=f"fusing frames: {done}/{total}")

        def loaded(inp) -> None:
            for note in inp.notes:
                _note(note)
            if inp.kind == "frame" and inp.meta.get("depth") is None:
                _note(inp.meta["depth_source"], "[cyan]note:[/]")
            prog.update(task, description="fitting: step 1")

        def step(it: int, n: int, gain: float) -> None:
            prog.update(task, description=f"fitting: step {it + 1}, {n} cuboids (last gain {gain:.0f})")

        res, written = job.run(
            request.path, out_json, request.image, on_loaded=loaded, progress=step, fuse_progress=fused
        )
    for note in res.info.warnings:
        _note(note)
    level = unlevelled_warning(res.record, job.outputs) if res.kind == "frame" else None
    if level:
        _note(level)
    if stream is not None and res.kind == "frame":
        stream.log(res.record, res.depth_m, res.rgb)
    return res, written


def cuboid_table(result) -> Table:
    world = result.kind == "room"
    table = Table(
        title=f"{len(result.cuboids)} cuboids" + (" (world frame)" if world else ""), title_justify="left"
    )
    for col in ("#", "kind", "centre x, y, z (m)", "size x, y, z (m)", "inlier gain"):
        table.add_column(col, justify="left" if col == "kind" else "right")
    for i, c in enumerate(result.cuboids):
        r, g, b = c.to_json(i)["color"]
        table.add_row(
            f"[rgb({r},{g},{b})]■[/] {i}",
            c.kind,
            ", ".join(f"{v:6.2f}" for v in c.center),
            ", ".join(f"{2 * v:5.2f}" for v in c.half_size),
            f"{c.inlier_gain:.1f}",
        )
    return table


def print_fit(res, written: list[Path]) -> None:
    """The cuboids, the fit in one line and the files written."""
    info, t = res.info, res.record.timing_s
    out.print(cuboid_table(res))
    if res.kind == "room":
        how = f"{info.voxel_m * 100:.1f} cm voxels, {info.visibility} visibility, up {info.room_up.source}"
        out.print(
            f"fitted {len(res.cuboids)} cuboids to {info.n_points} points ({how}) in {t['total']:.2f} s "
            f"(reading {t.get('load', 0.0):.2f} s); {objects_summary(info.objects)}; stop: {info.stop_reason}"
        )
    else:
        out.print(
            f"fitted {len(res.cuboids)} cuboids to {info.n_points} points in {t['total']:.2f} s "
            f"({'depth {:.2f} s, '.format(t['depth']) if 'depth' in t else ''}"
            f"solve {t['solve']:.2f} s, score {t['score']:.2f} s; stop: {info.stop_reason})"
        )
    for p in written:
        out.print(f"wrote {p}")


def fit_folder(job: Job, request: FitRequest, stream=None) -> None:
    """Fit every input of a folder (its depth maps, its photos, or its rooms), one JSON each, on the
    request's engine; inputs whose outputs exist are skipped; ends with a summary, exit 1 if any failed.
    With ``rrd`` among the outputs a folder of frames gets one recording of all its frames."""
    from cuboidcli.export.files import FOLDER_RECORDING, result_names, results_folder
    from cuboidcli.job import fit_task, folder_inputs, folder_tasks
    from cuboidcli.scaleout import Outcome, Summary

    folder, quiet, source = request.path, request.outputs.quiet, request.source
    files, left_out = folder_inputs(folder, source)
    if left_out and not quiet:
        what = (
            "colour images (photos?)"
            if source == "depth"
            else "files that are not colour images (depth maps?)"
        )
        _note(f"left out {left_out} {what}", "[cyan]note:[/]")
    if not files:
        kind = {
            "photo": "colour images (*.png, *.jpg, ...)",
            "depth": "depth maps (*.png, *.npy, *.npz, *.exr)",
        }.get(source, "rooms")
        fail(f"no {kind} in {folder}")
    out_dir = request.outputs.output or results_folder(folder)
    if out_dir.suffix == ".json" or (out_dir.exists() and not out_dir.is_dir()):
        fail(f"-o {out_dir}: give a folder for the results of the folder {folder}")
    check_writable(out_dir)
    if "rrd" in job.outputs and job.kind == "frame":  # one recording of the whole folder, written at the end
        job = replace(job, outputs=tuple(k for k in job.outputs if k != "rrd"))
        stream = FolderRecording(stream)
    tasks, skipped = folder_tasks(job.in_folder(folder), files, out_dir, request.run.skip_existing)
    summary = Summary()
    for f in skipped:
        summary.add(Outcome(f.name, "skipped"))
    if not quiet and summary.skipped:
        _note(
            f"skipped {summary.skipped} inputs whose outputs exist in {out_dir}/ (--no-skip-existing fits "
            "them again)",
            "[cyan]note:[/]",
        )
    said_source = False

    def describe(i: int, res: Outcome) -> str:
        nonlocal said_source
        n, seconds, what = res.value
        if job.kind == "room":
            return f"{names[i]}: {n} cuboids, {what} points, {seconds:.1f} s"
        if source == "photo" and not said_source:
            _note(what, "[cyan]note:[/]")
            said_source = True
        if stream is not None:
            stream.add(tasks[i][2])
        return f"{names[i]}: {n} cuboids, {seconds:.2f} s"

    label = f"fitting {len(tasks)} {'rooms' if job.kind == 'room' else 'frames'} on {request.run.describe()}"
    # a room found in a sub-folder is named with its folders (two may both be room.ply)
    names = [Path(t[1]).relative_to(folder).as_posix() for t in tasks]
    run_with_progress(fit_task, tasks, names, request.run, summary, quiet, label, describe)
    if isinstance(stream, FolderRecording):
        path = stream.write(out_dir / FOLDER_RECORDING, [out_dir / n for n in result_names(files)])
        if not quiet:
            out.print(f"wrote {path}")
    end_of_run(summary, out_dir, quiet)

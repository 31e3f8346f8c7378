"""`cuboids fit ROOM`: a point cloud, a mesh or a posed RGB-D sequence folder, fitted as one room in its
own world frame, or every room of a folder. Parses what only rooms take, prints, and calls
:meth:`cuboidcli.api.Fitter.fit_scene` (one room) or :mod:`cuboidcli.room_folder` (a folder)."""

from __future__ import annotations

from pathlib import Path

from rich.progress import TimeElapsedColumn
from rich.table import Table

from cuboidcli.cli.common import fail, out, progress_bar, user_errors
from cuboidcli.cli.fit_frames import Engine, check_extras, scene_kinds
from cuboidcli.cli.options import DEFAULTS, fit_config
from cuboidcli.cli.scale_options import end_of_run, ray_target, run_with_progress
from cuboidcli.fitting.scene import VISIBILITY_CHOICES, SceneConfig


def fit_room_command(o: dict) -> None:
    """``cuboids fit`` with the options ``o`` for a room, or for a folder of rooms."""
    from cuboidcli.folder import fitter_for
    from cuboidcli.scene import is_scene_input

    folder = not is_scene_input(o["image"])
    ray_at = ray_target(o["workers"], o["ray"], o["ray_address"])
    if (o["workers"] > 1 or ray_at is not None) and not folder:
        fail("--workers and --ray fit the rooms of a folder; one room is fitted in one process")
    if o["sampler"] == "learned":
        fail("--sampler learned weighs the pixels of a depth map; a room is fitted with sequential")
    config = fit_config(o)
    # A room's own default number of cuboids stands unless --max-cuboids says otherwise.
    max_cuboids = None if o["max_cuboids"] == DEFAULTS.max_cuboids else o["max_cuboids"]
    scene = scene_config(max_cuboids, o["visibility"], o["up"], o["voxel"])
    scenes = scene_kinds(o, ("html", "mjcf", "urdf", "usd"))
    weights, onnx = (None if o[k] is None else str(o[k]) for k in ("weights", "onnx"))
    with user_errors():
        check_extras(scenes)
        try:
            fitter = fitter_for(config, weights, onnx)
        except (ValueError, FileNotFoundError, ImportError) as e:
            fail(str(e))
        if folder:
            from cuboidcli.room_folder import RoomJob

            job = RoomJob(
                config, scene, weights, onnx, o["unit"], o["every"], o["intrinsics"], o["depth_scale"],
                o["glb"], o["ply"], o["with_points"], scenes,
            )  # fmt: skip
            engine = Engine(o["workers"], ray_at)
            fit_rooms_folder(job, o["image"], o["output"], o["quiet"], engine, o["skip_existing"])
            return
        outputs = {k: o[k] for k in ("glb", "ply", "overlay", "with_points")}
        fit_room(
            fitter, o["image"], scene, o["output"], unit=o["unit"], every=o["every"],
            intrinsics=o["intrinsics"], depth_scale=o["depth_scale"], outputs={**outputs, "scenes": scenes},
            quiet=o["quiet"],
        )  # fmt: skip


def scene_config(
    max_cuboids: int | None, visibility: str, up: str | None, voxel_m: float | None
) -> SceneConfig:
    """The room's settings from the command line (one line and exit 2 for a bad value)."""
    from cuboidcli.io.depth import InputError
    from cuboidcli.scene import parse_up

    if visibility not in VISIBILITY_CHOICES:
        fail(f"--visibility {visibility!r}: choose {', '.join(VISIBILITY_CHOICES)}")
    try:
        given_up = parse_up(up)
    except InputError as e:
        fail(str(e))
    kw = {"visibility": visibility, "up": given_up}
    if max_cuboids is not None:
        kw["max_cuboids"] = max_cuboids
    if voxel_m is not None:
        kw["voxel_m"] = voxel_m
    try:
        return SceneConfig(**kw)
    except ValueError as e:
        fail(str(e))


def scene_table(result) -> Table:
    table = Table(title=f"{len(result.cuboids)} cuboids (world frame)")
    for col in ("#", "kind", "centre (m)", "size (m)", "gain"):
        table.add_column(col, justify="right" if col in ("#", "gain") else "left")
    for i, c in enumerate(result.cuboids):
        centre = ", ".join(f"{v:.2f}" for v in c.center)
        size = " x ".join(f"{2 * v:.2f}" for v in c.half_size)
        table.add_row(str(i), c.kind, centre, size, f"{c.inlier_gain:.0f}")
    return table


def fit_room(
    fitter,
    path: Path,
    scene: SceneConfig,
    output: Path | None,
    *,
    unit: str,
    every: int,
    intrinsics: str | None,
    depth_scale: float | None,
    outputs: dict,
    quiet: bool,
) -> None:
    """Fit one room and write its outputs; bad input is one line and exit 2 with nothing written."""
    from cuboidcli.export.files import result_name
    from cuboidcli.io.depth import InputError

    out_json = output or Path(result_name(path))
    if out_json.suffix.lower() != ".json":
        out_json = out_json / "cuboids.json" if out_json.is_dir() else out_json.with_suffix(".json")
    with progress_bar("{task.description}", TimeElapsedColumn(), transient=True, disable=quiet) as bar:
        fuse = bar.add_task("fusing frames", total=None, visible=path.is_dir())
        fitting = bar.add_task("fitting", total=scene.max_cuboids, visible=False)

        def fused(done: int, total: int) -> None:
            bar.update(fuse, completed=done, total=total)

        def step(it: int, n: int, gain: float) -> None:
            bar.update(
                fitting, visible=True, completed=n, description=f"fitting: {n} cuboids (last gain {gain:.0f})"
            )

        try:
            res = fitter.fit_scene(
                path, scene=scene, unit=unit, every=every, intrinsics=intrinsics, depth_scale=depth_scale,
                progress=step, fuse_progress=fused,
            )  # fmt: skip
        except InputError as e:
            fail(str(e))
        except ValueError as e:
            fail(str(e))
    written = res.save(out_json, **outputs)
    if quiet:
        return
    for w in res.record.input.get("warnings", []) + res.info.fit.warnings:
        out.print(f"[yellow]warning:[/] {w}")
    out.print(scene_table(res))
    t, info = res.record.timing_s, res.info
    how = f"{info.voxel_m * 100:.1f} cm voxels, {info.visibility} visibility, up {info.up.source}"
    out.print(
        f"fitted {len(res.cuboids)} cuboids to {info.fit.n_points} points ({how}) in {t['total']:.2f} s "
        f"(reading {t.get('load', 0.0):.2f} s); stop: {info.fit.stop_reason}"
    )
    for p in written:
        out.print(f"wrote {p}")


def fit_rooms_folder(
    job, folder: Path, output: Path | None, quiet: bool, engine, skip_existing: bool
) -> None:
    """Fit every room of a folder (scan files, sequence sub-folders) on ``engine`` (local processes or
    Ray), one JSON each in ``output``; rooms whose outputs exist with the same settings are skipped; ends
    with a summary, exit 1 if any room failed."""
    from cuboidcli.cli.common import console
    from cuboidcli.export.files import results_folder
    from cuboidcli.folder import folder_tasks
    from cuboidcli.room_folder import fit_room_file, rooms_in
    from cuboidcli.scaleout import Outcome, Summary

    out_dir = output or results_folder(folder)
    if out_dir.suffix == ".json" or (out_dir.exists() and not out_dir.is_dir()):
        fail(f"-o {out_dir}: give a folder for the rooms of {folder}")
    tasks, skipped = folder_tasks(job, rooms_in(folder), out_dir, skip_existing)
    summary = Summary()
    for room in skipped:
        summary.add(Outcome(room.name, "skipped"))
    if not quiet and summary.skipped:
        console.print(
            f"[cyan]note:[/] skipped {summary.skipped} rooms whose outputs exist in {out_dir}/",
            highlight=False,
        )

    def describe(i: int, res: Outcome) -> str:
        n, seconds, points = res.value
        return f"{res.name}: {n} cuboids, {points} points, {seconds:.1f} s"

    label = f"fitting {len(tasks)} rooms on {engine.describe()}"
    names = [Path(t[1]).name for t in tasks]
    run_with_progress(fit_room_file, tasks, names, engine, summary, quiet, label, describe)
    end_of_run(summary, out_dir, quiet)

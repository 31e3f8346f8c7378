"""`cuboids fit ROOM`: a point cloud, a mesh or a posed RGB-D sequence folder, fitted as one room in its
own world frame. Parses what only rooms take, prints, and calls :meth:`cuboidcli.api.Fitter.fit_scene`."""

from __future__ import annotations

from pathlib import Path

from rich.progress import TimeElapsedColumn
from rich.table import Table

from cuboidcli.cli.common import fail, out, progress_bar
from cuboidcli.cli.scale_options import end_of_run, run_with_progress
from cuboidcli.fitting.scene import VISIBILITY_CHOICES, SceneConfig


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
    from cuboidcli.io.depth import InputError

    out_json = output or Path(f"{path.name if path.is_dir() else path.stem}_cuboids.json")
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
    from cuboidcli.room_folder import fit_room_file, out_name, room_is_complete, rooms_in
    from cuboidcli.scaleout import Outcome, Summary

    rooms = rooms_in(folder)
    out_dir = output or Path(f"{folder.name}_cuboids")
    if out_dir.suffix == ".json" or (out_dir.exists() and not out_dir.is_dir()):
        fail(f"-o {out_dir}: give a folder for the rooms of {folder}")
    summary = Summary()
    todo = []
    for room in rooms:
        if skip_existing and room_is_complete(out_dir / out_name(room), job):
            summary.add(Outcome(room.name, "skipped"))
        else:
            todo.append(room)
    if not quiet and summary.skipped:
        console.print(
            f"[cyan]note:[/] skipped {summary.skipped} rooms whose outputs exist in {out_dir}/",
            highlight=False,
        )
    tasks = [(job, str(r), str(out_dir / out_name(r))) for r in todo]

    def describe(i: int, res: Outcome) -> str:
        n, seconds, points = res.value
        return f"{res.name}: {n} cuboids, {points} points, {seconds:.1f} s"

    label = f"fitting {len(tasks)} rooms on {engine.describe()}"
    run_with_progress(fit_room_file, tasks, [r.name for r in todo], engine, summary, quiet, label, describe)
    end_of_run(summary, out_dir, quiet)

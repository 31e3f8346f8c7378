"""``cuboids evaluate DIR`` on room scans: DIR holds ``scene_*/`` folders with ``gt.json`` (or is one), as
``cuboids synth --views N`` writes them. Parses what only rooms take, refuses what only frames take, shows
progress and prints one table; the work is :mod:`cuboidcli.evaluation.scene_run`."""

from __future__ import annotations

import math
import sys
from pathlib import Path

import typer
from rich.progress import TimeElapsedColumn
from rich.table import Table

from cuboidcli.cli.common import console, fail, out, progress_bar, user_errors

#: Options that only room scans take: given, they make ``cuboids evaluate`` evaluate room scans.
ROOM_ONLY = ("visibility", "bare", "baseline")
#: Options of ``cuboids evaluate`` that only frames take: (parameter, flag, default); refused for rooms.
FRAME_ONLY = (
    ("split", "--split", None),
    ("frames", "--frames", None),
    ("runs", "--runs", 1),
    ("workers", "--workers", 1),
    ("ray", "--ray", False),
    ("ray_address", "--ray-address", None),
    ("auc", "--auc", None),
    ("save_fits", "--save-fits", False),
    ("fits", "--fits", None),
    ("rgb", "--rgb", False),
    ("depth_model", "--depth-model", None),
    ("grid_step", "--grid-step", None),
)
#: Table rows: (aggregate key, label, decimals); the table has one column per method.
ROWS = (
    ("n_cuboids", "cuboids per room", 1),
    ("auc20cm_pct", "AUC@20 cm %", 1),
    ("auc5cm_pct", "AUC@5 cm %", 1),
    ("object_recall_pct", "object recall %", 1),
    ("object_precision_pct", "object precision %", 1),
    ("object_box_recall_iou0.25_pct", "object box recall@0.25 %", 1),
    ("object_box_recall_iou0.5_pct", "object box recall@0.5 %", 1),
    ("object_box_precision_iou0.25_pct", "object box precision@0.25 %", 1),
    ("part_box_recall_iou0.25_pct", "part box recall@0.25 %", 1),
    ("shell_box_recall_iou0.25_pct", "shell recall@0.25 %", 1),
    ("seconds", "seconds per room", 2),
)
ROOMS = "Room scans: "


def visibility_option():
    return typer.Option(
        None,
        "--visibility",
        help=ROOMS + "how points count against a cuboid, as cuboids fit ROOM takes it: auto, views, "
        "inside or plain.",
        show_default="auto",
    )


def bare_option():
    return typer.Option(
        False,
        "--bare",
        help=ROOMS + "fit each scan's fused points as a bare cloud, without the cameras that saw them.",
    )


def baseline_option():
    return typer.Option(
        False,
        "--baseline",
        help=ROOMS + "also score the Open3D planes + clusters baseline on the same points.",
    )


def refuse(options: dict, refused, why: str) -> None:
    """One line and exit status 2 for the first of ``refused`` ((parameter, flag, default)) that is given:
    "FLAG ``why``"."""
    for name, flag, default in refused:
        if options[name] != default:
            fail(f"{flag} {why}")


def output_folder(options: dict, written: str) -> Path | None:
    """``--output``, checked to be a folder or nothing yet (``written`` is the file put into it)."""
    output = options["output"]
    if output is not None and output.exists() and not output.is_dir():
        fail(f"--output {output} is a file; give a folder ({written} is written into it)")
    return output


def limited(items: list, options: dict) -> list:
    """The first ``--limit`` of ``items`` (all without it); one line and exit status 2 for a limit below 1."""
    limit = options["limit"]
    if limit is not None and limit < 1:
        fail(f"--limit must be at least 1 (got {limit})")
    return items if limit is None else items[:limit]


def is_room_run(data: Path, options: dict) -> bool:
    """Whether ``cuboids evaluate`` evaluates room scans: DATA holds some, or a room-only option is given."""
    from cuboidcli.evaluation.scene_run import scan_candidates

    return any(options.get(k) not in (None, False) for k in ROOM_ONLY) or bool(scan_candidates(data))


def _fmt(value: float, decimals: int) -> str:
    return f"{value:.{decimals}f}" if value is not None and math.isfinite(value) else "-"


def scenes_table(report, n: int) -> Table:
    """One column per method: its aggregate over the rooms (recalls and precisions pooled over the rooms'
    objects and boxes, the rest means per room). Metrics down the side, so that the table fits 80 columns."""
    title = (
        f"{n} room scan{'s' if n != 1 else ''}: objects by point majority, object boxes by 3D IoU, "
        "shell slabs by IoU in their plane"
    )
    table = Table(title=title, title_justify="left")
    table.add_column("")
    for label in report.labels.values():
        table.add_column(label, justify="right")
    for key, label, decimals in ROWS:
        cells = (_fmt(report.aggregate[m].get(key, math.nan), decimals) for m in report.labels)
        table.add_row(label, *cells)
    return table


def fitter_from_options(options: dict):
    """The configured Fitter (presets, then the given options over them) and the presets applied; a whole
    scan is fitted, so the parts that need a depth map are refused."""
    from cuboidcli.cli.options import fit_config
    from cuboidcli.evaluation.presets import resolve
    from cuboidcli.job import fitter_for
    from cuboidcli.weights import shipped_path

    config, _, applied = resolve(options["preset"])
    config = fit_config(options, config)
    if config.sampler == "learned":
        fail(
            "the learned sampler weighs the pixels of a depth map; a room is fitted with sequential or local"
        )
    if config.solver == "onnx":
        fail("--solver onnx needs an --onnx file, which cuboids evaluate does not take")
    weights = options["weights"]
    if weights is not None and not shipped_path(weights).exists():
        fail(f"--weights {weights}: no such folder or file")
    try:
        return fitter_for(config, None if weights is None else str(shipped_path(weights)), None), applied
    except (ValueError, FileNotFoundError, ImportError) as e:
        fail(str(e))


def evaluate_rooms(data: Path, options: dict) -> None:
    """Fit and score every room scan of ``data``; ``options`` are ``cuboids evaluate``'s parameters."""
    from cuboidcli.evaluation import scene_run as run
    from cuboidcli.evaluation.scene_run import SCAN_FILES

    folders = run.scan_candidates(data)
    if not folders:
        fail(
            f"{data}: no room scans (folders scene_*/ with {' and '.join(SCAN_FILES)}, as cuboids synth "
            "--views N writes them)"
        )
    # a scan cut short (its ground truth is written last) is an error, not a room left out quietly
    for folder in folders:
        if not run.is_room_scan(folder):
            missing = [name for name in SCAN_FILES if not (folder / name).is_file()]
            fail(f"{folder}: not a complete room scan (no {' or '.join(missing)})")
    refuse(
        options, FRAME_ONLY, "applies to frames; room scans take --limit, --visibility, --bare and --baseline"
    )
    output = output_folder(options, "scenes.json")
    folders = limited(folders, options)
    settings = run.SceneEvalSettings(bare=options["bare"], baseline=options["baseline"])
    with user_errors():
        fitter, applied = fitter_from_options(options)
        with progress_bar("{task.description}", TimeElapsedColumn(), transient=True) as bar:
            task = bar.add_task("rooms", total=len(folders))

            def progress(done: int, total: int, what: str) -> None:
                bar.update(task, completed=done, description=what)

            try:
                report = run.evaluate_scenes(folders, fitter, settings, progress)
            except ValueError as e:  # a scan that cannot be read or fitted (InputError is one)
                fail(str(e))
        out.print(scenes_table(report, len(folders)))
        if output is not None:
            provenance = {
                "command": " ".join(["cuboids", *sys.argv[1:]]),
                "data": str(data.resolve()),
                "presets": applied,
                "settings": {"fit": fitter.config.for_kind("room").to_dict(), **settings.to_dict()},
            }
            path = run.write_scene_report(output / "scenes.json", report, provenance)
            out.print(f"wrote {path}")
    empty = [r["scene"] for r in report.rows if r["method"] == run.FITTED and r["n_cuboids"] == 0]
    if empty:
        console.print(f"[yellow]warning:[/] no cuboid fitted in {', '.join(empty)}", highlight=False)

"""``cuboids evaluate DIR`` on labelled real scans in ScanNet's layout (``NAME_bbox.npy`` with ``NAME.ply`` or
``NAME_vert.npy``): checks the folder and the options, shows progress, prints the scans' table, the pooled
row and the recall per class; the scoring is :mod:`cuboidcli.evaluation.scannet`."""

from __future__ import annotations

import sys
from pathlib import Path

from rich import box
from rich.progress import TimeElapsedColumn
from rich.table import Table

from cuboidcli.cli import evaluate_scene as rooms
from cuboidcli.cli.common import console, fail, out, progress_bar, user_errors

#: What a labelled scan is, for the messages.
LAYOUT = "NAME_bbox.npy with NAME.ply or NAME_vert.npy"
#: Options of ``cuboids evaluate`` these scans do not take: the frames' (:data:`.evaluate_scene.FRAME_ONLY`)
#: and the room scans' own. A scan is a bare point cloud already, and no baseline is scored on it.
NOT_FOR_SCANS = (*rooms.FRAME_ONLY, ("bare", "--bare", False), ("baseline", "--baseline", False))


def is_scannet_run(data: Path) -> bool:
    """Whether DATA is a folder of labelled scans: it holds a ``NAME_bbox.npy``."""
    from cuboidcli.evaluation.scannet import labelled_names

    return data.is_dir() and bool(labelled_names(data))


def _names(data: Path, options: dict) -> list[str]:
    """The scans to evaluate: every labelled scan of DATA, or those of ``--scans``, cut to ``--limit``."""
    from cuboidcli.evaluation.scannet import has_points, labelled_names

    everything = labelled_names(data)
    # a scan whose points are missing (a copy cut short) is an error, not a scan left out quietly
    for name in everything:
        if not has_points(data, name):
            fail(f"{data / name}: a labelled scan without its points (no {name}.ply or {name}_vert.npy)")
    names = everything
    if options["scans"] is not None:
        names = [n for n in dict.fromkeys(options["scans"].replace(" ", "").split(",")) if n]
        unknown = [n for n in names if n not in everything]
        if unknown:
            fail(f"--scans: no scan {', '.join(unknown)} in {data} (it has {', '.join(everything)})")
    return rooms.limited(names, options)


def _table(table) -> Table:
    """A :class:`~cuboidcli.evaluation.tables.TextTable` of scans as a rich table; the pooled row (the last)
    ruled off. No vertical rules and one space between columns, so that eleven columns fit 80."""
    drawn = Table(title=table.title, title_justify="left", box=box.SIMPLE_HEAD, show_edge=False, padding=0)
    for i, header in enumerate(table.headers):
        drawn.add_column(header, justify="left" if i == 0 else "right", no_wrap=True)
    for i, row in enumerate(table.rows):
        drawn.add_row(*row, end_section=i == len(table.rows) - 2)
    return drawn


def evaluate_scannet(data: Path, options: dict) -> None:
    """Fit and score the labelled scans of ``data``; ``options`` are ``cuboids evaluate``'s parameters."""
    from cuboidcli.evaluation.scannet import evaluate_scans
    from cuboidcli.evaluation.scannet_report import LEGEND, scans_table, summary_lines, write_scannet_report

    names = _names(data, options)
    rooms.refuse(options, NOT_FOR_SCANS, f"does not apply to labelled scans ({LAYOUT})")
    output = rooms.output_folder(options, "scannet.json")
    with user_errors():
        fitter, applied = rooms.fitter_from_options(options)
        with progress_bar("{task.description}", TimeElapsedColumn(), transient=True) as bar:
            task = bar.add_task("scans", total=len(names))

            def progress(done: int, total: int, name: str, row: dict | None) -> None:
                bar.update(task, completed=done, description=name if row is None else "scans")

            try:
                rows, pooled = evaluate_scans(data, fitter, names, progress)
            except ValueError as e:  # a scan that cannot be read or fitted (InputError is one)
                fail(str(e))
        n = f"{len(rows)} labelled scan{'s' if len(rows) != 1 else ''}"
        out.print(_table(scans_table(rows, pooled, f"{n}, then pooled: object boxes by 3D IoU")))
        for line in (*LEGEND, *summary_lines(pooled)):
            out.print(line, highlight=False)
        if output is not None:
            provenance = {
                "command": " ".join(["cuboids", *sys.argv[1:]]),
                "data": str(data.resolve()),
                "presets": applied,
                "seed": fitter.config.seed,
                "settings": {"fit": fitter.config.for_kind("room").to_dict()},
            }
            path = write_scannet_report(output / "scannet.json", rows, pooled, provenance)
            out.print(f"wrote {path}")
    empty = [r["scan"] for r in rows if r["cuboids"] == 0]
    if empty:
        console.print(f"[yellow]warning:[/] no cuboid fitted in {', '.join(empty)}", highlight=False)

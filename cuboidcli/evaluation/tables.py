"""The results of ``cuboids evaluate`` as the tables it prints, in plain text: each :class:`TextTable` has a
title, column headers and rows of cells (mean ± std over runs), every column right-aligned; a front end
only draws them (the command draws them with rich). Also the line that names the method and the running
means the progress bar shows.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

from cuboidcli.evaluation.auc import auc_key

if TYPE_CHECKING:
    from cuboidcli.evaluation.runner import EvalReport
    from cuboidcli.fitting.config import FitConfig

#: Columns of the results table in the paper's order (Table 1): (aggregate key, header, decimals).
COLUMNS = (
    ("time_s", "time (s)", 2),
    ("cuboids", "|M|", 1),
    ("coverage_pct", "cover %", 1),
    ("oa_covered_cm", "OA cov. cm", 1),
    ("oa_all_cm", "OA all cm", 1),
)


@dataclass(frozen=True)
class TextTable:
    """A table as text: its title, the column headers and the rows of cells, every column right-aligned."""

    title: str
    headers: list[str]
    rows: list[list[str]]


def cell(mean: float | None, std: float, decimals: int, runs: int) -> str:
    """``mean`` with ``decimals`` decimals, ``± std`` with several runs; ``-`` for a missing value."""
    if mean is None or not math.isfinite(mean):
        return "-"
    return f"{mean:.{decimals}f}" + (f" ± {std:.{decimals}f}" if runs > 1 else "")


def _summary_table(report: EvalReport, title: str, cols: list[tuple[str, str, int]]) -> TextTable:
    """One row: the summary's (mean, std) of each column's key."""
    runs = len(report.runs)
    row = [cell(*report.summary.get(k, (math.nan, math.nan)), d, runs) for k, _, d in cols]
    return TextTable(title, [header for _, header, _ in cols], [row])


def _frames(n: int) -> str:
    return f"{n} frame{'' if n == 1 else 's'}"


def results_table(report: EvalReport, label: str) -> TextTable:
    """The paper's metrics (Table 1 column order), mean ± std over runs."""
    cols = list(COLUMNS) + [(auc_key(cm), f"AUC@{cm:g} %", 1) for cm in report.settings.auc_cm]
    title = f"{label}: {_frames(report.runs[0]['frames'])}"
    if len(report.runs) > 1:
        title += f", mean ± std of {len(report.runs)} runs (seeds {report.seeds[0]}..{report.seeds[-1]})"
    return _summary_table(report, title, cols)


def gt_table(report: EvalReport) -> TextTable | None:
    """Recall and precision of ground-truth cuboids (greedy one-to-one matching at 3D IoU), if any."""
    keys = [k for k in report.runs[0] if k.startswith(("recall_iou", "precision_iou"))]
    if not keys:
        return None
    cols = [(k, k.replace("_iou", "@").replace("_pct", " %"), 1) for k in keys]  # recall@0.25 %
    title = f"ground-truth cuboids ({report.runs[0]['frames_with_gt']} frames), 3D IoU"
    return _summary_table(report, title, cols)


def objects_table(report: EvalReport) -> TextTable | None:
    """Object recall and precision from the instance images (synthetic data), if any."""
    if "object_recall_pct" not in report.runs[0]:
        return None
    cols = [
        ("object_recall_pct", "object recall %", 1),
        ("object_precision_pct", "object precision %", 1),
        ("objects_eligible", "eligible objects", 0),
    ]
    n = report.runs[0]["frames_with_instances"]
    return _summary_table(report, f"objects of the instance images ({_frames(n)})", cols)


def shape_table(report: EvalReport) -> TextTable | None:
    """Axis angles against gravity / the room's axes and the support of the visible faces, if measured."""
    if "support_median_pct" not in report.runs[0]:
        return None
    cols = [
        ("axis_angle_gravity_median_deg", "∠up °", 1),
        ("axis_angle_manhattan_median_deg", "∠room °", 1),
        ("slabs", "slabs", 0),
        ("slabs_within_3deg_pct", "slabs ≤3° %", 1),
        ("room_slabs_within_3deg_pct", "room ≤3° %", 1),
        ("support_median_pct", "support %", 1),
        ("support_mean_pct", "mean %", 1),
    ]
    run = report.runs[0]
    refs = ", ".join(
        f"{src} {run.get(f'frames_gravity_{src}', 0)}"
        for src in ("fit", "synthetic", "estimated", "none")
        if run.get(f"frames_gravity_{src}", 0)
    )
    return _summary_table(report, f"shape: medians over cuboids; axes of: {refs}", cols)


def gravity_table(report: EvalReport) -> TextTable | None:
    """Error of the gravity estimate on frames with a known gravity (synthetic data), if any."""
    if "frames_with_known_gravity" not in report.runs[0]:
        return None
    cols = [
        ("gravity_error_median_deg", "median °", 2),
        ("gravity_error_max_deg", "max °", 2),
        ("gravity_within_2deg_pct", "≤2° %", 1),
        ("gravity_estimates_missing", "no estimate", 0),
    ]
    of_fit = sum(1 for m in report.frames[0] if m.shape is not None and m.shape.gravity_error_of == "fit")
    whose = "fit" if of_fit else "depth estimate"
    n = report.runs[0]["frames_with_known_gravity"]
    return _summary_table(report, f"gravity error, {whose} ({_frames(n)})", cols)


def parsimony_table(report: EvalReport) -> TextTable | None:
    """The parsimony curve: AUC and coverage of the first k cuboids (selection order), mean ± std."""
    if "parsimony" not in report.summary:
        return None
    mean, std = report.summary["parsimony"]
    runs = len(report.runs)
    keys = [(auc_key(cm), f"AUC@{cm:g} %") for cm in report.settings.auc_cm]
    keys.append(("coverage_pct", "cover %"))
    rows = []
    for i, k in enumerate(mean["k"]):
        cells = []
        for key, _ in keys:
            m, sd = mean.get(key), std.get(key)
            cells.append("-" if m is None else cell(m[i], sd[i], 1, runs))
        rows.append([str(k), *cells])
    return TextTable("parsimony: first k cuboids", ["k", *(header for _, header in keys)], rows)


def report_tables(report: EvalReport, label: str) -> list[TextTable]:
    """Every table the report has, in the order the command prints them: the results (titled ``label``),
    then those of ground-truth cuboids, objects, shape, gravity and parsimony where measured."""
    more = (gt_table, objects_table, shape_table, gravity_table, parsimony_table)
    return [results_table(report, label), *(t for make in more if (t := make(report)) is not None)]


def method_label(config: FitConfig, applied: list[str], fits: Path | None) -> str:
    """What was evaluated, in a few words: the presets applied, sampler, solver, OAI, refinement and
    alignment, or the folder of saved fits."""
    if fits is not None:
        return f"saved fits ({fits.name})"
    oai = "OAI" if config.occlusion_aware else "no OAI"
    refined = ", refined" if getattr(config, "refine", False) else ""
    aligned = f", {config.align}-aligned" if getattr(config, "align", "free") != "free" else ""
    parts = [", ".join(applied)] if applied else []
    return " / ".join(parts + [f"{config.sampler}, {config.solver}, {oai}{refined}{aligned}"])


def running_line(running: dict[str, float]) -> str:
    """The running means of an evaluation in progress (|M|, coverage, OA, the first AUC, s/image)."""
    auc = next(
        (f"AUC@{k[3:].split('cm')[0]} {v:.1f}%" for k, v in running.items() if k.startswith("auc")), ""
    )
    oa = running.get("oa_all_cm", math.nan)
    return (
        f"|M| {running.get('cuboids', 0):.1f}  cov {running.get('coverage_pct', 0):.1f}%  "
        f"OA {oa:.1f} cm  {auc}  {running.get('time_s', math.nan):.2f} s/img"
    )

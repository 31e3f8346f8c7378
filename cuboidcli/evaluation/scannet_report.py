"""The results of scoring labelled real scans (:mod:`.scannet`) as a front end shows them: one table of the
scans' rows and the pooled row, the per-class recall as one line, and the JSON report. ``cuboids evaluate``
on a folder in ScanNet's layout and ``scripts/eval_scannet.py`` both draw these, so the columns are defined
once, here."""

from __future__ import annotations

import math
import os
from pathlib import Path

from cuboidcli.evaluation.scannet import class_recall
from cuboidcli.evaluation.tables import TextTable

#: Schema name of the JSON report.
SCHEMA = "cuboids-scannet/1"
#: Table columns: (row key, header, decimals); every column but the scan's name is a number. The up error
#: and the number of labelled boxes are in the rows and the report, and the up error under the table.
COLUMNS = (
    ("scan", "scan", None),
    ("recall_iou0.25_pct", "R@.25", 1),
    ("recall_iou0.5_pct", "R@.5", 1),
    ("precision_pct", "prec.", 1),
    ("ap_iou0.25_pct", "AP@.25", 1),
    ("ap_iou0.5_pct", "AP@.5", 1),
    ("objects", "boxes", 1),
    ("auc20cm_pct", "AUC@20", 1),
    ("auc5cm_pct", "AUC@5", 1),
    ("cuboids", "cuboids", 1),
    ("seconds", "s", 1),
)
#: What the headers mean, printed under the table (lines of at most 80 characters).
LEGEND = (
    "R@t, AP@t: recall and average precision at 3D IoU t (%); prec.: share of the",
    "object boxes on one labelled object (%); boxes: object boxes; AUC@d: points",
    "within d cm of a cuboid (area under the curve, %); s: seconds per scan",
)


def _cell(row: dict, key: str, decimals: int | None) -> str:
    value = row.get(key)
    if value is None or (isinstance(value, float) and math.isnan(value)):
        return "-"  # a ratio of nothing: no labelled box, or no per-point labels
    return str(value) if decimals is None else f"{value:.{decimals}f}"


def table_cells(row: dict) -> list[str]:
    """The cells of one scan's row or of a pooled row, in :data:`COLUMNS` order."""
    return [_cell(row, key, decimals) for key, _, decimals in COLUMNS]


def scans_table(rows: list[dict], pooled: dict, title: str = "") -> TextTable:
    """One line per scan, then the pooled row (recalls, precision and AP of the summed counts; the rest
    means; up error the largest)."""
    lines = [table_cells(r) for r in rows] + ([table_cells(pooled)] if rows else [])
    return TextTable(title, [header for _, header, _ in COLUMNS], lines)


def markdown_header() -> list[str]:
    """The header and rule lines of the table in Markdown."""
    return ["| " + " | ".join(h for _, h, _ in COLUMNS) + " |", "|" + "---|" * len(COLUMNS)]


def markdown_line(row: dict) -> str:
    """One row of the table in Markdown."""
    return "| " + " | ".join(table_cells(row)) + " |"


def summary_lines(pooled: dict) -> list[str]:
    """The lines under the table: the pooled recall at IoU 0.25 of each class (most labelled first), the
    labelled boxes per scan, the largest up error and how many scans stopped at the cuboid cap."""
    parts = [f"{name} {m}/{n}" for name, (m, n) in class_recall(pooled).items()]
    lines = ["recall at IoU 0.25 by class (pooled): " + (", ".join(parts) or "no labelled boxes")]
    if pooled.get("scans"):
        lines += [
            f"labelled boxes per scan: {pooled['labelled']:.1f}; largest up error (vs labelled floor): "
            f"{pooled['up_error_deg']:.1f} deg",
            f"{pooled['capped']} of {pooled['scans']} scans stopped at the cuboid cap",
        ]
    return lines


def write_scannet_report(path: str | os.PathLike, rows: list[dict], pooled: dict, provenance: dict) -> Path:
    """Write the scans' ``rows``, the ``pooled`` row, the pooled recall per class and ``provenance``
    (command, data, settings, seed) to ``path`` as JSON, atomically (schema :data:`SCHEMA`)."""
    from cuboidcli.evaluation.scene_run import write_report

    classes = {name: {"matched": m, "labelled": n} for name, (m, n) in class_recall(pooled).items()}
    body = {"pooled": pooled, "class_recall_iou0.25": classes, "scans": rows}
    return write_report(path, SCHEMA, body, provenance)

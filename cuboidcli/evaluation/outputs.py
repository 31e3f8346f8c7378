"""Output files of an evaluation: ``metrics.json`` (aggregates, rows, provenance), ``frames.csv`` and
``cuboids.csv``."""

from __future__ import annotations

import csv
import io
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cuboidcli import __version__
from cuboidcli.evaluation.provenance import machine_info
from cuboidcli.io.atomic import atomic_write_json, atomic_write_text

if TYPE_CHECKING:
    from cuboidcli.evaluation.runner import EvalReport


def _clean(obj):
    """JSON-safe copy: NaN and inf become null, tuples lists, paths strings."""
    if isinstance(obj, float):
        return obj if math.isfinite(obj) else None
    if isinstance(obj, dict):
        return {str(k): _clean(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [_clean(v) for v in obj]
    if isinstance(obj, Path):
        return str(obj)
    if isinstance(obj, np.generic):
        return _clean(obj.item())
    return obj


def frame_rows(report: EvalReport) -> list[dict]:
    """One row per (run, frame) in reporting units, with the run index and seed first."""
    return [
        {"run": r, "seed": seed, **m.row()} for r, seed in enumerate(report.seeds) for m in report.frames[r]
    ]


def cuboid_rows(report: EvalReport) -> list[dict]:
    """One row per (run, frame, predicted cuboid) with its shape measurements, run index and seed first."""
    return [
        {"run": r, "seed": seed, **row}
        for r, seed in enumerate(report.seeds)
        for m in report.frames[r]
        for row in m.cuboid_rows()
    ]


def _csv_text(rows: list[dict]) -> str:
    columns: list[str] = []
    for row in rows:
        columns += [k for k in row if k not in columns]
    buf = io.StringIO()
    writer = csv.DictWriter(buf, fieldnames=columns, lineterminator="\n")
    writer.writeheader()
    for row in rows:
        writer.writerow(
            {k: "" if isinstance(v, float) and not math.isfinite(v) else v for k, v in row.items()}
        )
    return buf.getvalue()


def write_outputs(
    report: EvalReport, out_dir: str | os.PathLike, meta: dict | None = None, frames=None
) -> list[Path]:
    """Write ``metrics.json`` (aggregates, per-frame rows, per-cuboid rows, config, provenance),
    ``frames.csv``, when the shape measurements were made ``cuboids.csv``, and ``report.html``
    (:mod:`.report`; skipped without plotly). ``frames`` (the evaluated frames) lets the report draw the
    worst frames' panels from saved fits."""
    out_dir = Path(out_dir)
    rows = frame_rows(report)
    per_cuboid = cuboid_rows(report)
    doc = {
        "schema": "cuboids-eval/1",
        "version": __version__,
        **(meta or {}),
        "config": report.config.to_dict("frame"),
        "auc_cm": list(report.settings.auc_cm),
        "seeds": report.seeds,
        "summary": {k: {"mean": m, "std": s} for k, (m, s) in report.summary.items()},
        "runs": report.runs,
        "frames": rows,
        "per_cuboid": per_cuboid,
        "failed_frames": report.failures,
        "weights_sha256": report.weights,
        "machine": machine_info(),
    }
    paths = [atomic_write_json(out_dir / "metrics.json", _clean(doc))]
    paths.append(atomic_write_text(out_dir / "frames.csv", _csv_text(rows)))
    if per_cuboid:
        paths.append(atomic_write_text(out_dir / "cuboids.csv", _csv_text(per_cuboid)))
    from cuboidcli.evaluation.report import write_report

    try:
        paths.append(write_report(report, out_dir, meta, frames))
    except ImportError:  # plotly (the viz extra) is not installed: the numbers are written, the page is not
        pass
    return paths

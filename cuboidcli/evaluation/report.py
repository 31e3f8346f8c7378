"""``report.html`` of an evaluation: the metrics with their provenance, the curves, the per-frame table and
the worst frames' panels, in one self-contained page (plotly's JavaScript embedded, images inline).

The plots use what the evaluation computes: the parsimony curve (``summary["parsimony"]``: AUC@X and
coverage of the first k cuboids, mean ± std over runs) and, per frame, AUC@X for every threshold, drawn
as the share of frames reaching each AUC value (the evaluation pools the distances into AUC statistics and
keeps no per-point distances, so a pooled recall-over-distance curve cannot be drawn from its outputs).
Without plotly (the ``viz`` extra) :func:`write_report` raises the one-line ImportError of
:func:`cuboidcli.export.html.import_plotly`; :func:`cuboidcli.evaluation.outputs.write_outputs` then skips
the page.
"""

from __future__ import annotations

import html
import json
import math
import os
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cuboidcli import __version__
from cuboidcli.export.html import import_plotly, page, plot_div, png_data_uri
from cuboidcli.io.atomic import atomic_write_text

if TYPE_CHECKING:
    from cuboidcli.evaluation.runner import EvalReport, EvalSettings

#: Panels of at most this many worst frames (lowest AUC at the largest threshold) are embedded.
WORST_FRAMES = 4
#: Panels are embedded at most this wide (pixels).
PANEL_WIDTH = 1200

SORT_JS = """
function sortTable(th){
  const table=th.closest('table'), body=table.tBodies[0], col=th.cellIndex;
  const asc=th.dataset.dir!=='asc'; th.dataset.dir=asc?'asc':'desc';
  for(const h of table.tHead.rows[0].cells){if(h!==th){delete h.dataset.dir;}}
  const key=r=>{const c=r.cells[col], v=c.dataset.v; return v===undefined?c.textContent:parseFloat(v);};
  const rows=Array.from(body.rows).sort((a,b)=>{const x=key(a),y=key(b);
    const nx=typeof x==='number'&&!isNaN(x), ny=typeof y==='number'&&!isNaN(y);
    if(nx&&ny){return asc?x-y:y-x;} if(nx!==ny){return nx?-1:1;}
    return asc?String(x).localeCompare(String(y)):String(y).localeCompare(String(x));});
  for(const r of rows){body.appendChild(r);}
}
"""


def _num(v) -> float | None:
    if isinstance(v, bool) or not isinstance(v, int | float | np.number):
        return None
    v = float(v)
    return v if math.isfinite(v) else None


def _cell(v, digits: int = 2) -> str:
    n = _num(v)
    if n is not None:
        text = f"{n:.{digits}f}" if isinstance(v, float | np.floating) else str(v)
        return f'<td class=n data-v="{n!r}">{text}</td>'
    return f"<td>{'' if v is None or isinstance(v, float) else html.escape(str(v))}</td>"


def _auc_keys(report: EvalReport) -> list[tuple[float, str]]:
    from cuboidcli.evaluation.auc import auc_key

    return [(float(cm), auc_key(cm)) for cm in report.settings.auc_cm]


def metrics_table(report: EvalReport) -> str:
    """Every scalar aggregate: mean, and ± std over runs when there are several."""
    runs = len(report.seeds)
    head = "<tr><th>metric</th><th>mean</th>" + ("<th>std</th>" if runs > 1 else "") + "</tr>"
    rows = []
    for key, value in report.summary.items():
        if key == "parsimony":
            continue
        mean, std = value
        rows.append(
            f"<tr><td>{html.escape(key)}</td>{_cell(mean)}" + (_cell(std) if runs > 1 else "") + "</tr>"
        )
    return f'<table id="metrics"><thead>{head}</thead><tbody>\n' + "\n".join(rows) + "\n</tbody></table>"


def run_meta(
    report: EvalReport, settings: EvalSettings, command: str, dataset, presets: list[str], method: str
) -> dict:
    """What ``metrics.json`` and the page record of a run besides its metrics (:func:`provenance` shows
    them): the command line, the dataset (as :func:`~cuboidcli.evaluation.runner.load_frames` describes
    it), the presets applied, the method's label, the folders of saved fits and weights, the input, the
    depth model (a hub id as given, a file resolved) and the frames done and skipped. ``settings``: as
    given to the run (a weights folder left out is recorded as None, not as the default the run used)."""
    s = settings
    model = s.depth_model
    return {
        "command": command,
        "dataset": dataset,
        "presets": presets,
        "method": method,
        "fits_dir": None if s.fits_dir is None else str(Path(s.fits_dir).resolve()),
        "weights_dir": None if s.weights_dir is None else str(Path(s.weights_dir).resolve()),
        "input": "rgb" if s.rgb else "depth",
        "depth_model": None
        if model is None
        else (model if isinstance(model, str) else str(Path(model).resolve())),
        "frames_done": report.counts.done,
        "frames_skipped": report.counts.skipped,
    }


def provenance(report: EvalReport, meta: dict) -> str:
    """Version, command, data, seeds, the resolved settings (folded) and the machine."""
    dataset = meta.get("dataset") or {}
    items = [
        ("cuboids version", __version__),
        ("method", meta.get("method")),
        ("command", meta.get("command")),
        ("presets", ", ".join(meta.get("presets") or []) or None),
        ("data", dataset.get("path") if isinstance(dataset, dict) else dataset),
        (
            "format / split",
            " / ".join(str(dataset.get(k)) for k in ("format", "split") if k in dataset)
            if isinstance(dataset, dict)
            else None,
        ),
        ("frames", len(report.frames[0]) if report.frames else 0),
        ("seeds", ", ".join(str(s) for s in report.seeds)),
        ("AUC thresholds (cm)", ", ".join(f"{c:g}" for c in report.settings.auc_cm)),
        ("frames failed", len(report.failures)),
    ]
    rows = "\n".join(
        f"<tr><th>{html.escape(k)}</th><td>{html.escape(str(v))}</td></tr>"
        for k, v in items
        if v not in (None, "")
    )
    config = html.escape(json.dumps(report.config.to_dict("frame"), indent=1, default=str))
    weights = html.escape(json.dumps(report.weights, indent=1)) if report.weights else ""
    return (
        f'<table id="provenance">{rows}</table>\n'
        f"<details><summary>settings (resolved)</summary><pre>{config}</pre></details>\n"
        + (
            f"<details><summary>weights (SHA-256)</summary><pre>{weights}</pre></details>\n"
            if weights
            else ""
        )
    )


def parsimony_figure(report: EvalReport):
    """AUC@X and coverage of the first k cuboids (mean over runs, ± std as error bars); None without it."""
    if "parsimony" not in report.summary:
        return None
    go = import_plotly()
    mean, std = report.summary["parsimony"]
    fig = go.Figure()
    for key in [k for k in mean if k != "k"]:
        err = std.get(key) if len(report.seeds) > 1 else None
        fig.add_trace(
            go.Scatter(
                x=mean["k"],
                y=mean[key],
                mode="lines+markers",
                name=key.replace("_pct", " %"),
                error_y={"type": "data", "array": err} if err else None,
            )
        )
    fig.update_layout(
        title="Parsimony: the first k cuboids (selection order)",
        xaxis_title="k (cuboids)",
        yaxis_title="%",
        yaxis_range=[0, 100],
        height=420,
        margin={"l": 50, "r": 20, "t": 50, "b": 45},
    )
    return fig


def frame_auc_figure(report: EvalReport):
    """Per AUC threshold: the share of frames (all runs) whose AUC@X is at least a value, over the value."""
    go = import_plotly()
    fig = go.Figure()
    rows = [m.row() for run in report.frames for m in run]
    for cm, key in _auc_keys(report):
        vals = np.sort(np.array([r[key] for r in rows if _num(r.get(key)) is not None], dtype=np.float64))
        if not vals.size:
            continue
        share = 100.0 * (vals.size - np.arange(vals.size)) / vals.size
        fig.add_trace(
            go.Scatter(x=vals, y=share, mode="lines+markers", line_shape="hv", name=f"AUC@{cm:g}cm")
        )
    fig.update_layout(
        title="Recall per frame: share of frames with AUC@X at least the value",
        xaxis_title="AUC@X of a frame (%)",
        yaxis_title="frames (%)",
        xaxis_range=[0, 100],
        yaxis_range=[0, 102],
        height=420,
        margin={"l": 50, "r": 20, "t": 50, "b": 45},
    )
    return fig


def recall_figure(report: EvalReport):
    """The recall curve of each run: the share of all frames' points within a distance of the abstraction
    (pooled as the AUC is; AUC@X is the area under it up to X, divided by X). None without curves."""
    from cuboidcli.evaluation.auc import RECALL_CURVE_CM, pooled_recall_pct

    go = import_plotly()
    fig = go.Figure()
    for r, frames in enumerate(report.frames):
        curve = pooled_recall_pct(frames)
        if curve is not None:
            fig.add_trace(go.Scatter(x=list(RECALL_CURVE_CM), y=curve, mode="lines", name=f"run {r}"))
    if not fig.data:
        return None
    for cm, _ in _auc_keys(report):
        fig.add_vline(x=cm, line_dash="dot", line_color="grey")
    fig.update_layout(
        title="Recall: points within a distance of the cuboids (occlusion-aware)",
        xaxis_title="OA distance (cm)",
        yaxis_title="points (%)",
        yaxis_range=[0, 102],
        height=420,
        margin={"l": 50, "r": 20, "t": 50, "b": 45},
    )
    return fig


def frames_table(report: EvalReport) -> str:
    """The per-frame rows of frames.csv, sortable by clicking a column header."""
    rows = [  # the rows of frames.csv (evaluation/outputs.py: frame_rows)
        {"run": r, "seed": seed, **m.row()} for r, seed in enumerate(report.seeds) for m in report.frames[r]
    ]
    columns: list[str] = []
    for row in rows:
        columns += [k for k in row if k not in columns]
    head = "".join(f'<th class="sortable" onclick="sortTable(this)">{html.escape(c)}</th>' for c in columns)
    body = "\n".join("<tr>" + "".join(_cell(r.get(c)) for c in columns) + "</tr>" for r in rows)
    return (
        f'<table id="frames"><thead><tr>{head}</tr></thead><tbody>\n{body}\n</tbody></table>\n'
        '<p class="muted">click a column header to sort (again: the other way).</p>'
    )


def worst_frames(report: EvalReport, n: int = WORST_FRAMES) -> list[tuple[int, int, str, float]]:
    """The ``n`` (run, seed, frame, AUC) with the lowest AUC at the largest threshold, lowest first."""
    cm, key = max(_auc_keys(report))
    scored = [
        (m.auc[cm].value * 100.0, r, seed, m.name)
        for r, (seed, run) in enumerate(zip(report.seeds, report.frames, strict=True))
        for m in run
        if cm in m.auc
    ]
    scored.sort()
    return [(r, seed, name, auc) for auc, r, seed, name in scored[:n]]


def _saved_panel(report: EvalReport, seed: int, name: str, frames_by_name: dict) -> np.ndarray | None:
    """The frame's panel: a saved ``<name>_panel.png`` beside its saved fit, else rendered from the saved
    fit and the frame's depth map (and RGB image, if it has one); None when the fit was not saved."""
    import cv2

    from cuboidcli.export.overlay import render_images
    from cuboidcli.io.result import read_result

    s = report.settings
    candidates = []
    if s.save_fits_dir is not None:
        candidates.append(Path(s.save_fits_dir) / f"seed{seed}" / f"{name}.json")  # runner.saved_fit_path
    if s.fits_dir is not None:
        candidates.append(Path(s.fits_dir) / f"{name}.json")
    for fit in candidates:
        png = fit.with_name(f"{fit.stem}_panel.png")
        if png.is_file():
            img = cv2.imread(str(png), cv2.IMREAD_COLOR)
            if img is not None:
                return cv2.cvtColor(img, cv2.COLOR_BGR2RGB)
        frame = frames_by_name.get(name)
        if fit.is_file() and frame is not None:
            result = read_result(fit)
            depth = frame.depth_m()
            rgb = frame.rgb() if callable(getattr(frame, "rgb", None)) else None
            if rgb is not None and rgb.shape[:2] != depth.shape:
                rgb = None
            return render_images(result.camera, result.cuboids, rgb=rgb, depth_m=depth)["panel"]
    return None


def worst_section(report: EvalReport, frames) -> str:
    cm, _key = max(_auc_keys(report))
    by_name = {f.name: f for f in frames or []}
    parts = []
    for _r, seed, name, auc in worst_frames(report):
        title = f"{html.escape(name)} (seed {seed}): AUC@{cm:g}cm {auc:.1f} %"
        try:
            panel = _saved_panel(report, seed, name, by_name)
        except Exception as e:  # a panel that cannot be made leaves a note, not a failed report
            panel = None
            title += f" (no panel: {html.escape(str(e))})"
        if panel is None:
            parts.append(f"<h3>{title}</h3>")
        else:
            uri = png_data_uri(panel, PANEL_WIDTH)
            parts.append(
                f'<h3>{title}</h3>\n<img class="panel" alt="panel of {html.escape(name)}" src="{uri}">'
            )
    if not any("<img" in p for p in parts):
        parts.append(
            '<p class="muted">no panels: they are drawn from the saved fits (run with --save-fits, or '
            "evaluate saved fits with --fits).</p>"
        )
    return "\n".join(parts)


def report_html(report: EvalReport, meta: dict | None = None, frames=None) -> str:
    """The page as a string (see :func:`write_report`)."""
    meta = meta or {}
    figs = [parsimony_figure(report), recall_figure(report), frame_auc_figure(report)]
    figs = [f for f in figs if f is not None]
    plots = "\n".join(plot_div(f, first=i == 0) for i, f in enumerate(figs))
    title = f"cuboids evaluate: {meta.get('method') or 'report'}"
    body = (
        f"<h1>{html.escape(title)}</h1>\n<h2>Provenance</h2>\n{provenance(report, meta)}\n"
        '<div style="display:flex;flex-wrap:wrap;gap:24px;align-items:flex-start">\n'
        f"<div><h2>Metrics</h2>\n{metrics_table(report)}\n"
        '<p class="muted">column meanings: docs/evaluate.md; AUC pooled over all points of all<br>frames, '
        "the other values means over frames; std: population std over runs.</p></div>\n"
        f'<div style="flex:1;min-width:520px"><h2>Curves</h2>\n{plots}\n</div></div>\n'
        f"<h2>Frames</h2>\n{frames_table(report)}\n"
        f"<h2>Worst frames</h2>\n{worst_section(report, frames)}\n"
        f"<script>{SORT_JS}</script>"
    )
    return page(title, body)


def write_report(
    report: EvalReport, out_dir: str | os.PathLike, meta: dict | None = None, frames=None
) -> Path:
    """Write ``<out_dir>/report.html`` atomically: provenance (version, command, data, settings), the
    metrics, the parsimony and per-frame AUC curves, the sortable per-frame table and the panels of the
    worst frames (with ``frames``, the evaluated frames, and saved fits). ImportError (one line) without
    plotly."""
    return atomic_write_text(Path(out_dir) / "report.html", report_html(report, meta, frames))

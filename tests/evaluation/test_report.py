"""report.html of `cuboids evaluate`: metrics with provenance, two plots, a sortable per-frame table, the
worst frames' panels; self-contained and rendered by headless Chromium offline."""

from __future__ import annotations

import re

import numpy as np
import pytest
from typer.testing import CliRunner

from cuboidcli.evaluation.outputs import write_outputs
from cuboidcli.evaluation.runner import EvalSettings, evaluate, load_frames
from tests.evaluation.test_evaluate import FAST_OPTS, SMALL, make_folder
from tests.export.test_html import (
    assert_self_contained,
    chromium,
    markup_outside_scripts,
    needs_chromium,
)


@pytest.fixture(scope="module")
def folder(tmp_path_factory):
    root = tmp_path_factory.mktemp("data")
    make_folder(root)
    return root


@pytest.fixture(scope="module")
def run_dir(folder, tmp_path_factory):
    """Two seeds with saved fits, written as the command does, with the frames for the panels."""
    out = tmp_path_factory.mktemp("run")
    frames, dataset = load_frames(folder)
    report = evaluate(frames, SMALL, EvalSettings(runs=2, save_fits_dir=out / "fits"))
    meta = {"command": "cuboids evaluate data", "dataset": dataset, "method": "default"}
    paths = write_outputs(report, out, meta, frames=frames)
    assert out / "report.html" in paths
    return out, report


def test_cli_writes_report_with_metrics_two_plots_and_frames_table(app, folder, tmp_path):
    out = tmp_path / "out"
    res = CliRunner().invoke(app, ["evaluate", str(folder), *FAST_OPTS, "-o", str(out)])
    assert res.exit_code == 0, res.output
    text = (out / "report.html").read_text(encoding="utf-8")
    assert_self_contained(text)
    assert 'id="metrics"' in text and "auc20cm_pct" in text and "cuboids version" in text
    markup = markup_outside_scripts(text)
    assert markup.count('class="plotly-graph-div"') == 3  # the parsimony, recall and per-frame AUC plots
    assert "Recall: points within a distance of the cuboids" in text
    assert 'id="frames"' in text and text.count('onclick="sortTable(this)"') > 5
    assert "no panels" in text  # no saved fits


def test_report_holds_provenance_curves_and_worst_panels(run_dir):
    out, report = run_dir
    text = (out / "report.html").read_text(encoding="utf-8")
    assert_self_contained(text)
    for needle in (
        "cuboids evaluate data",
        "seeds",
        "0, 1",
        "settings (resolved)",
        "&quot;hypotheses&quot;: 48",
    ):
        assert needle in text, needle
    mean = report.summary["auc20cm_pct"][0]
    assert f"{mean:.2f}" in text
    assert markup_outside_scripts(text).count("data:image/png;base64,") == 4  # the 4 worst frames' panels
    worst = sorted(m.auc[20.0].value for run in report.frames for m in run)[0]
    assert f"AUC@20cm {100 * worst:.1f} %" in text


@needs_chromium
def test_chromium_renders_the_report_and_sorts_the_table(run_dir, tmp_path):
    out, report = run_dir
    img = chromium(out / "report.html", tmp_path, size="1200,1400")
    drawn = np.abs(img.astype(np.int32) - 255).max(axis=2) > 40
    assert drawn.mean() > 0.05, drawn.mean()
    plots = img[300:1200, 500:]  # the two plots beside the metrics table: plotly's grey plot backgrounds
    assert (np.abs(plots.astype(np.int32) - [229, 236, 246]).max(axis=2) <= 3).mean() > 0.2
    # click the auc20cm_pct header: once ascending, twice descending (the DOM after the clicks)
    text = (out / "report.html").read_text(encoding="utf-8")
    header = re.findall(r'<table id="frames"><thead><tr>(.*?)</tr>', text)[0]
    col = re.findall(r"<th[^>]*>(.*?)</th>", header).index("auc20cm_pct")
    click = f"document.querySelector('#frames thead th:nth-child({col + 1})').click();"
    for clicks, order in ((1, 1), (2, -1)):
        page = tmp_path / f"clicked{clicks}.html"
        page.write_text(
            text.replace("</body>", f"<script>{click * clicks}</script></body>"), encoding="utf-8"
        )
        dom = chromium(page, tmp_path, screenshot=False)
        body = re.findall(r'<table id="frames">.*?<tbody>(.*?)</tbody>', dom, flags=re.S)[0]
        rows = re.findall(r"<tr>(.*?)</tr>", body, flags=re.S)
        values = [float(re.findall(r'data-v="([^"]*)"', re.findall(r"<td[^>]*>", r)[col])[0]) for r in rows]
        assert len(values) == 6 and values == sorted(values, key=lambda v: order * v), (clicks, values)

"""`cuboids evaluate`: the paper's metrics over a dataset (NYU Depth v2 or a generic folder)."""

from __future__ import annotations

import sys
from pathlib import Path

import typer
from rich.markup import escape
from rich.progress import TimeRemainingColumn
from rich.table import Table

from cuboidcli.cli import evaluate_scannet as scannet
from cuboidcli.cli import evaluate_scene as rooms
from cuboidcli.cli.common import console, fail, out, progress_bar, user_errors
from cuboidcli.cli.options import config_option, device_option, fast_option, fit_config, override_option
from cuboidcli.cli.scale_options import (
    ray_address_option,
    ray_option,
    ray_target,
    skip_existing_option,
    workers_option,
)
from cuboidcli.evaluation.presets import EVAL_SAMPLERS, EVAL_SOLVERS
from cuboidcli.weights import shipped_path

PRESET = "the preset's"


def _parse_list(text: str, what: str, cast=float) -> list:
    try:
        values = [cast(v) for v in text.replace(" ", "").split(",") if v]
    except ValueError:
        fail(f"{what} {text!r}: give comma-separated numbers, e.g. 20,5")
    if not values:
        fail(f"{what} is empty")
    return values


def _config(preset: str | None, auc: str | None, options: dict):
    """The presets' FitConfig with the given options set over it, the AUC thresholds (cm) and the presets
    applied."""
    from cuboidcli.evaluation.presets import resolve

    config, auc_cm, applied = resolve(preset)
    config = fit_config(options, config, samplers=EVAL_SAMPLERS, solvers=EVAL_SOLVERS)
    if auc is not None:
        auc_cm = tuple(_parse_list(auc, "--auc"))
        if any(x <= 0 for x in auc_cm):
            fail(f"--auc {auc!r}: thresholds must be positive (cm)")
    return config, auc_cm, applied


def _rich(table) -> Table:
    """A :class:`~cuboidcli.evaluation.tables.TextTable` as a rich table."""
    drawn = Table(title=table.title, title_justify="left")
    for header in table.headers:
        drawn.add_column(header, justify="right")
    for row in table.rows:
        drawn.add_row(*row)
    return drawn


def evaluate(
    data: Path = typer.Argument(
        ...,
        help="Dataset folder: NYU Depth v2 (nyu_depth_v2_labeled.mat + splits.mat), the generic layout "
        "(depth/, cameras.json, optional cuboids/), room scans (scene_*/gt.json: cuboids synth --views) or "
        "labelled real scans in ScanNet's layout (NAME_bbox.npy with NAME.ply or NAME_vert.npy).",
    ),
    split: str = typer.Option(
        None, "--split", help="test | train | val (NYU default: test; a folder: per its splits.json)."
    ),
    limit: int = typer.Option(
        None, "--limit", help="Evaluate only the first N frames (room scans: rooms; labelled scans: scans)."
    ),
    frames: str = typer.Option(None, "--frames", help="Comma-separated frame names, e.g. nyu_0001,nyu_0002."),
    scans: str = typer.Option(
        None, "--scans", help="Labelled scans: comma-separated scan names, e.g. scene0001_00,scene0003_01."
    ),
    runs: int = typer.Option(1, "--runs", help="Repeat with seeds SEED..SEED+R-1; report mean ± std."),
    workers: int = workers_option(),
    ray: bool = ray_option(),
    ray_address: str = ray_address_option(),
    skip_existing: bool = skip_existing_option(
        "With --save-fits: score the frames whose fit OUT/fits holds (same settings) from that file "
        "instead of fitting them again, so that an interrupted evaluation resumes."
    ),
    preset: str = typer.Option(
        None,
        "--preset",
        help="Baseline/variant: default, ours, ours-neural, seqransac-oai, seqransac, uniform, "
        "paper, outdoor; combine with commas (seqransac,outdoor).",
    ),
    sampler: str = override_option("sampler", of=PRESET, more=f"Here: {', '.join(EVAL_SAMPLERS)}."),
    solver: str = override_option("solver", of=PRESET, more=f"Here: {', '.join(EVAL_SOLVERS)}."),
    hypotheses: int = override_option("hypotheses", of=PRESET),
    max_cuboids: int = override_option("max_cuboids", of=PRESET),
    grid_step: int = override_option("grid_step", of=PRESET),
    occlusion_aware: bool = override_option("occlusion_aware", of=PRESET),
    refine: bool = override_option("refine", of=PRESET),
    fast: bool = fast_option(),
    auc: str = typer.Option(None, "--auc", help="AUC upper bounds in cm (default: 20,5; outdoor 50,10)."),
    output: Path = typer.Option(None, "--output", "-o", help="Write metrics.json and frames.csv here."),
    save_fits: bool = typer.Option(
        False, "--save-fits", help="Also write each fit as cuboids/1 JSON: OUT/fits/seed<S>/<frame>.json."
    ),
    fits: Path = typer.Option(
        None,
        "--fits",
        help="Evaluate saved cuboids/1 files <DIR>/<frame>.json instead of fitting "
        "(e.g. OUT/fits/seed0, or another method's output converted to cuboids/1).",
    ),
    weights: Path = typer.Option(
        None, "--weights", help="Network weights: a folder or a .pt file (default: shipped)."
    ),
    rgb: bool = typer.Option(
        False, "--rgb", help="Fit to depth estimated from each RGB image; score against the true depth."
    ),
    depth_model: str = typer.Option(
        None,
        "--depth-model",
        help="With --rgb: the depth model, as cuboids fit takes it: hf:owner/name, a save_pretrained "
        "folder, a metric .onnx or a .pt of the built-in network.",
        show_default="shipped",
    ),
    align: str = override_option("align", of=PRESET),
    seed: int = config_option("seed", more="With --runs: the first run's."),
    device: str = device_option(),
    visibility: str = rooms.visibility_option(),
    bare: bool = rooms.bare_option(),
    baseline: bool = rooms.baseline_option(),
) -> None:
    """Fit every frame and report the paper's metrics: time, |M|, coverage, OA-L2 distances, AUC.

    Also the parsimony curve (AUC and coverage of the first k cuboids), the cuboids' axis angles to
    gravity and the room's axes, the support of their visible faces, and, where the dataset has them,
    object recall and precision (instance images) and the gravity error (known gravity) (docs/evaluate.md).
    Room scans (DATA/scene_*/gt.json, from cuboids synth --views N): each room is fitted whole and scored
    in its world frame (--visibility, --bare; --baseline adds Open3D planes + clusters; -o: scenes.json).
    Labelled real scans (DATA/NAME_bbox.npy with NAME.ply or NAME_vert.npy, as ScanNet's detection data):
    each scan is fitted whole and its object boxes scored against the labelled furniture boxes (recall and
    AP at IoU 0.25 and 0.5, precision, recall per class; --scans, --limit; -o: scannet.json).
    """
    options = dict(locals())  # the parameters named after FitConfig fields set them over the presets'
    if scannet.is_scannet_run(data):  # DATA holds NAME_bbox.npy files
        return scannet.evaluate_scannet(data, options)
    if scans is not None:
        fail(f"--scans names labelled scans ({scannet.LAYOUT}); {data} holds none")
    if rooms.is_room_run(data, options):  # DATA holds room scans, or a room-only option was given
        return rooms.evaluate_rooms(data, options)
    from cuboidcli.evaluation.outputs import write_outputs
    from cuboidcli.evaluation.report import run_meta
    from cuboidcli.evaluation.runner import EvalSettings, load_frames
    from cuboidcli.evaluation.runner import evaluate as run
    from cuboidcli.evaluation.tables import method_label, report_tables, running_line

    if runs < 1:
        fail(f"--runs must be at least 1 (got {runs})")
    ray_at = ray_target(workers, ray, ray_address)
    if save_fits and output is None:
        fail("--save-fits writes into the output folder: pass -o OUT_DIR too")
    if fits is not None and not fits.is_dir():
        fail(f"--fits {fits}: folder not found")
    if fits is not None and (runs > 1 or save_fits):
        fail("--fits evaluates fixed cuboids: drop --runs and --save-fits")
    if weights is not None:
        weights = shipped_path(weights)
    hub_model = depth_model is not None and depth_model.startswith("hf:")
    if depth_model is not None and not hub_model:
        depth_model = shipped_path(depth_model)
    if weights is not None and not weights.exists():
        fail(f"--weights {weights}: no such folder or file")
    if depth_model is not None and not rgb:
        fail("--depth-model applies to --rgb (fitting from the RGB images)")
    if depth_model is not None and not hub_model and not depth_model.exists():
        fail(f"--depth-model {depth_model}: no such file or folder")
    if rgb and fits is not None:
        fail("--fits evaluates saved cuboids: drop --rgb")
    names = _parse_list(frames, "--frames", str) if frames is not None else None
    with user_errors():
        config, auc_cm, applied = _config(preset, auc, options)
        frame_list, dataset = load_frames(data, split, names, limit)
        settings = EvalSettings(
            auc_cm=auc_cm,
            runs=runs,
            seed=seed,
            workers=workers,
            fits_dir=fits,
            save_fits_dir=output / "fits" if save_fits else None,
            weights_dir=weights,
            rgb=rgb,
            depth_model=depth_model,
            ray=ray_at,
            skip_existing=skip_existing,
        )
        n_runs = len(settings.seeds)
        progress = progress_bar(
            "{task.description}", TimeRemainingColumn(), "{task.fields[running]}", transient=True
        )
        with progress as prog:
            task = prog.add_task("run 1", total=len(frame_list) * n_runs, running="")

            def on_frame(ev) -> None:
                prog.update(
                    task,
                    completed=ev.run * ev.total + ev.done,
                    running=running_line(ev.running),
                    description=f"run {ev.run + 1}/{ev.runs}" if ev.runs > 1 else "frames",
                )

            def on_failed(r: int, outcome) -> None:
                seed = f" (seed {settings.seeds[r]})" if n_runs > 1 else ""
                console.print(
                    f"[red]failed[/] {outcome.name}{seed}: {escape(outcome.message)}",
                    highlight=False,
                    soft_wrap=True,
                )

            try:
                report = run(frame_list, config, settings, progress=on_frame, on_failed=on_failed)
            except ValueError as e:  # the engine could not start (Ray missing, a bad address)
                fail(str(e))
        label = method_label(config, applied, fits) + (" from RGB" if rgb else "")
        for table in report_tables(report, label):
            out.print(_rich(table))
        empty = sum(r.get("frames_without_cuboids", 0) for r in report.runs)
        if empty:
            console.print(
                f"[yellow]warning:[/] {empty} fit(s) without any cuboid: their points count with "
                "zero recall, and in the OA means with their distance to the camera",
                highlight=False,
            )
        if output is not None:
            command = " ".join(["cuboids", *sys.argv[1:]])
            meta = run_meta(report, settings, command, dataset, applied, label)
            for p in write_outputs(report, output, meta, frames=frame_list):
                out.print(f"wrote {p}")
            if save_fits:
                out.print(f"wrote {report.counts.done} fits under {output / 'fits'}")
        if report.counts.skipped or report.counts.failed:
            out.print(
                f"frames: {report.counts.line()} (skipped: scored from their saved fit; failed: left out "
                "of the metrics)"
            )
    if report.failures:
        failed = len({f["frame"] for f in report.failures})
        fail(
            f"{failed} of {len(frame_list)} frames could not be evaluated (listed above"
            f"{' and in ' + str(output / 'metrics.json') if output is not None else ''}); the metrics are "
            "over the other frames",
            code=1,
        )


def register(app: typer.Typer) -> None:
    app.command("evaluate")(evaluate)

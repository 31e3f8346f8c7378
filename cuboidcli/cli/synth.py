"""``cuboids synth``: write a synthetic RGB-D dataset with ground-truth cuboids."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import typer
from rich.progress import TimeElapsedColumn, TimeRemainingColumn

from cuboidcli.cli.common import console, fail, progress_bar, user_errors


def synth(
    out_dir: Path = typer.Argument(
        ..., help="Dataset folder to write (created if missing; frames with the same names are replaced)."
    ),
    count: int = typer.Option(100, "--count", "-n", help="Number of frames."),
    seed: int = typer.Option(0, "--seed", help="Dataset seed; frame i is generated from (seed, i)."),
    preset: str = typer.Option("nyu", "--preset", help="Camera intrinsics preset: nyu, tum or scannet."),
    width: int | None = typer.Option(
        None,
        "--width",
        help="Image width in pixels (intrinsics are scaled from the preset; default: the preset's).",
    ),
    height: int | None = typer.Option(
        None, "--height", help="Image height in pixels (default: keeps the preset's aspect ratio)."
    ),
    workers: int = typer.Option(1, "--workers", "-j", help="Processes generating frames (same output)."),
    inpaint: bool = typer.Option(
        False, "--inpaint/--no-inpaint", help="Fill depth holes (dense maps like NYU's labelled set)."
    ),
    clean: bool = typer.Option(
        False, "--clean", help="Exact depth: no noise, quantisation or holes (range limits stay)."
    ),
    shadows: bool = typer.Option(True, "--shadows/--no-shadows", help="Cast shadows in the RGB images."),
) -> None:
    """Write COUNT synthetic indoor RGB-D frames with ground-truth cuboids into OUT_DIR.

    Layout: cameras.json, depth/<name>.png (uint16 mm, 0 = hole), rgb/<name>.png, instances/<name>.png,
    cuboids/<name>.json ("cuboids/1"), splits.json (index % 10: 0-7 train, 8 val, 9 test), synth.json.
    """
    from cuboidcli.camera import PRESETS, Camera

    if count < 1:
        fail(f"--count {count}: give at least 1 frame")
    if workers < 1:
        fail(f"--workers {workers}: give at least 1 process")
    if preset not in PRESETS:
        fail(f"--preset {preset!r}: choose one of {', '.join(PRESETS)}")
    if out_dir.exists() and not out_dir.is_dir():
        fail(f"{out_dir} is a file; give a folder for the dataset")
    base = Camera.preset(preset)
    w = width or (base.width if height is None else int(round(height * base.width / base.height)))
    h = height or int(round(w * base.height / base.width))
    if w < 16 or h < 16:
        fail(f"image size {w}x{h} is too small; give --width/--height of at least 16 pixels")
    camera = base if (w, h) == (base.width, base.height) else base.scaled(w / base.width, h / base.height)

    from cuboidcli.synth import SceneOptions, SensorOptions, split_of, write_dataset

    sensor = SensorOptions.clean() if clean else SensorOptions()
    options = SceneOptions(sensor=replace(sensor, inpaint=inpaint), shadows=shadows)
    start = time.perf_counter()
    progress = progress_bar("synth", TimeElapsedColumn(), "eta", TimeRemainingColumn(), transient=True)
    with user_errors(), progress as bar:
        task = bar.add_task("frames", total=count)
        try:
            write_dataset(
                out_dir,
                count,
                seed,
                camera,
                options,
                workers,
                progress=lambda done: bar.update(task, completed=done),
            )
        except (OSError, ValueError) as e:
            fail(f"cannot write the dataset to {out_dir}: {e}")
    elapsed = time.perf_counter() - start
    splits = [split_of(i) for i in range(count)]
    console.print(
        f"wrote {count} frames ({camera.width}x{camera.height}) to {out_dir} in {elapsed:.1f} s "
        f"({elapsed / count:.2f} s/frame); splits: {splits.count('train')} train, "
        f"{splits.count('val')} val, {splits.count('test')} test",
        highlight=False,
    )


def register(app: typer.Typer) -> None:
    app.command("synth")(synth)

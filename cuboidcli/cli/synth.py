"""``cuboids synth``: write a synthetic RGB-D dataset with ground-truth cuboids."""

from __future__ import annotations

import time
from dataclasses import replace
from pathlib import Path

import typer
from rich.progress import TimeElapsedColumn, TimeRemainingColumn

from cuboidcli.cli.common import console, fail, progress_bar, user_errors
from cuboidcli.cli.renamed import renamed_option, renamed_value, warn_renamed

#: Folder of room scan i under OUT_DIR (``cuboids evaluate`` finds the scans by this prefix).
SCENE_NAME = "scene_{:04d}"
#: The camera preset by default.
CAMERA = "nyu"


def _write_scan(root: str, seed: int, index: int, views: int, camera, options) -> None:
    """Generate room scan ``index`` from the entropy (seed, index) and write it to ``root``/scene_NNNN.
    At module level so that worker processes can run it."""
    from cuboidcli.synth.scan import generate_room_scan, write_room_scan

    write_room_scan(
        Path(root) / SCENE_NAME.format(index), generate_room_scan([seed, index], views, camera, options)
    )


def _write_scans(out_dir: Path, count: int, seed: int, views: int, camera, options, workers: int, done):
    """Write ``count`` room scans, in ``workers`` processes when > 1 (the same files); ``done(n)`` after
    each."""
    if workers == 1:
        for i in range(count):
            _write_scan(str(out_dir), seed, i, views, camera, options)
            done(i + 1)
        return
    from concurrent.futures import ProcessPoolExecutor, as_completed
    from multiprocessing import get_context

    # one ray-casting thread per process: the processes already fill the cores
    single = replace(options, threads=1)
    with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
        jobs = [pool.submit(_write_scan, str(out_dir), seed, i, views, camera, single) for i in range(count)]
        for n, job in enumerate(as_completed(jobs), 1):
            job.result()
            done(n)


def synth(
    out_dir: Path = typer.Argument(
        ..., help="Dataset folder to write (created if missing; frames with the same names are replaced)."
    ),
    count: int = typer.Option(100, "--count", "-n", help="Number of frames (with --views: of rooms)."),
    seed: int = typer.Option(0, "--seed", help="Dataset seed; frame (room) i is generated from (seed, i)."),
    camera: str = typer.Option(CAMERA, "--camera", help="Camera intrinsics preset: nyu, tum or scannet."),
    width: int | None = typer.Option(
        None,
        "--width",
        help="Image width in pixels (the --camera intrinsics are scaled to it; default: the camera's).",
    ),
    height: int | None = typer.Option(
        None, "--height", help="Image height in pixels (default: keeps the camera's aspect ratio)."
    ),
    workers: int = typer.Option(1, "--workers", "-j", help="Processes generating frames (same output)."),
    inpaint: bool = typer.Option(
        False, "--inpaint/--no-inpaint", help="Fill depth holes (dense maps like NYU's labelled set)."
    ),
    clean: bool = typer.Option(
        False, "--clean", help="Exact depth: no noise, quantisation or holes (range limits stay)."
    ),
    shadows: bool = typer.Option(True, "--shadows/--no-shadows", help="Cast shadows in the RGB images."),
    views: int | None = typer.Option(
        None,
        "--views",
        help="Write COUNT whole-room scans of this many views each instead of single frames: "
        "OUT_DIR/scene_0000/ etc., posed RGB-D sequences with world-frame ground truth (cuboids evaluate).",
    ),
    preset: str | None = renamed_option("--preset", "--camera"),
) -> None:
    """Write COUNT synthetic indoor RGB-D frames with ground-truth cuboids into OUT_DIR.

    Layout: cameras.json, depth/<name>.png (uint16 mm, 0 = hole), rgb/<name>.png, instances/<name>.png,
    cuboids/<name>.json ("cuboids/1"), splits.json (index % 10: 0-7 train, 8 val, 9 test), synth.json.

    With --views N: COUNT rooms, each scanned from N poses on a loop through the room, in folders
    scene_0000/ ... (room i from the seed (SEED, i): the room of frame i without --views). Each is a plain
    sequence (cameras.json, depth/, color/, pose/ 4x4 camera-to-world, instances/) that cuboids fit takes,
    with gt.json (world-frame ground truth, z up) and truth_points.npz (evaluation points).
    """
    from cuboidcli.camera import PRESETS, Camera

    # --camera counts as given when it is not the default: both spellings given is an error
    # (warned once the command line is checked: a refused one gets its one line alone)
    camera_name = renamed_value(camera, CAMERA, preset, "--preset", "--camera", warn=False)
    if count < 1:
        fail(f"--count {count}: give at least 1 frame")
    if workers < 1:
        fail(f"--workers {workers}: give at least 1 process")
    if views is not None and views < 1:
        fail(f"--views {views}: give at least 1 view per room")
    if camera_name not in PRESETS:
        fail(f"--camera {camera_name!r}: choose one of {', '.join(PRESETS)}")
    if out_dir.exists() and not out_dir.is_dir():
        fail(f"{out_dir} is a file; give a folder for the dataset")
    base = Camera.preset(camera_name)
    w = width or (base.width if height is None else int(round(height * base.width / base.height)))
    h = height or int(round(w * base.height / base.width))
    if w < 16 or h < 16:
        fail(f"image size {w}x{h} is too small; give --width/--height of at least 16 pixels")
    camera = base if (w, h) == (base.width, base.height) else base.scaled(w / base.width, h / base.height)
    if preset is not None:
        warn_renamed("--preset", "--camera")

    from cuboidcli.synth import SceneOptions, SensorOptions, split_of, write_dataset

    sensor = SensorOptions.clean() if clean else SensorOptions()
    options = SceneOptions(sensor=replace(sensor, inpaint=inpaint), shadows=shadows)
    start = time.perf_counter()
    progress = progress_bar("synth", TimeElapsedColumn(), "eta", TimeRemainingColumn(), transient=True)
    if views is not None:
        with user_errors(), progress as bar:
            task = bar.add_task("rooms", total=count)
            try:
                _write_scans(
                    out_dir, count, seed, views, camera, options, workers,
                    done=lambda n: bar.update(task, completed=n),
                )  # fmt: skip
            except (OSError, ValueError) as e:
                fail(f"cannot write the room scans to {out_dir}: {e}")
        elapsed = time.perf_counter() - start
        console.print(
            f"wrote {count} room scan{'s' if count > 1 else ''} ({views} view{'s' if views > 1 else ''} "
            f"each, {camera.width}x{camera.height}) to {out_dir}/scene_* in {elapsed:.1f} s "
            f"({elapsed / count:.2f} s/room)",
            highlight=False,
        )
        return
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

"""Writing synthetic frames into the generic dataset layout (:mod:`cuboidcli.io.dataset`).

Frame ``i`` of a dataset with seed ``S`` is named ``f"{i:06d}"`` and generated from the seed (S, i), so
the frames do not depend on the count, on the order of generation or on the number of workers: the same
seed gives byte-identical files, and a larger count only adds frames. Splits follow the index: within
every ten consecutive indices, 0-7 are train, 8 is val and 9 is test.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from concurrent.futures import ProcessPoolExecutor, as_completed
from dataclasses import replace
from multiprocessing import get_context
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.io.atomic import atomic_write_bytes, atomic_write_json
from cuboidcli.io.dataset import write_cameras
from cuboidcli.io.result import FitResult, write_result
from cuboidcli.synth.scene import Scene, SceneOptions, generate_scene

SPLITS = ("train", "val", "test")
DEPTH_SCALE = 0.001
"""Metres per depth-PNG unit (millimetres)."""


def frame_name(index: int) -> str:
    return f"{index:06d}"


def split_of(index: int) -> str:
    """train for index % 10 in 0..7, val for 8, test for 9."""
    r = index % 10
    return "train" if r < 8 else ("val" if r == 8 else "test")


def _png(image: np.ndarray) -> bytes:
    import cv2

    ok, buf = cv2.imencode(".png", image)
    if not ok:
        raise RuntimeError("PNG encoding failed")
    return buf.tobytes()


def depth_to_png_units(depth_m: np.ndarray, depth_scale: float = DEPTH_SCALE) -> np.ndarray:
    """Metres (H, W) -> uint16 units of ``depth_scale`` metres (0 stays 0 = missing), saturating at 65535."""
    return np.clip(np.rint(depth_m / depth_scale), 0, 65535).astype(np.uint16)


def scene_result(scene: Scene, name: str | None = None, options: SceneOptions | None = None) -> FitResult:
    """The ground truth of a scene as a "cuboids/1" result (cuboids in the camera frame, tagged)."""
    settings = {"generator": "cuboidcli.synth", "seed": scene.seed}
    if options is not None:
        settings["options"] = options.to_dict()
    inputs = {}
    if name is not None:
        inputs = {
            "depth": f"depth/{name}.png",
            "rgb": f"rgb/{name}.png",
            "instances": f"instances/{name}.png",
        }
    return FitResult(
        camera=scene.camera,
        cuboids=scene.cuboids,
        settings=settings,
        input=inputs,
        extras={
            "objects": scene.objects,
            "room": scene.room,
            "world_from_camera": [[float(v) for v in row] for row in scene.world_from_camera],
        },
    )


def write_frame(
    root: str | os.PathLike, name: str, scene: Scene, options: SceneOptions | None = None
) -> None:
    """Write one frame's depth, RGB, instance and ground-truth files (each atomically) under ``root``."""
    root = Path(root)
    atomic_write_bytes(root / "depth" / f"{name}.png", _png(depth_to_png_units(scene.depth_m)))
    atomic_write_bytes(root / "rgb" / f"{name}.png", _png(np.ascontiguousarray(scene.rgb[..., ::-1])))
    atomic_write_bytes(root / "instances" / f"{name}.png", _png(scene.instances.astype(np.uint16)))
    write_result(root / "cuboids" / f"{name}.json", scene_result(scene, name, options))


def _make_frame(root: str, seed: int, index: int, camera: Camera, options: SceneOptions) -> int:
    """Generate and write frame ``index``; runs in worker processes too, so it returns only the index."""
    write_frame(root, frame_name(index), generate_scene((seed, index), camera, options), options)
    return index


def write_dataset(
    out_dir: str | os.PathLike,
    count: int,
    seed: int = 0,
    camera: Camera | None = None,
    options: SceneOptions | None = None,
    workers: int = 1,
    progress: Callable[[int], None] | None = None,
) -> list[str]:
    """Generate ``count`` frames into ``out_dir`` in the generic dataset layout; returns the frame names.

    Writes ``depth/<name>.png`` (uint16 millimetres, 0 = hole), ``rgb/<name>.png``,
    ``instances/<name>.png`` (uint16 object ids, 0 = none), ``cuboids/<name>.json`` ("cuboids/1" ground
    truth), ``cameras.json``, ``splits.json`` and ``synth.json`` (the generator settings). ``camera``
    defaults to the NYU preset; ``workers`` > 1 generates frames in that many processes (identical
    output). ``progress`` is called with the number of frames finished so far.
    """
    if count < 1:
        raise ValueError(f"count must be at least 1 (got {count})")
    if workers < 1:
        raise ValueError(f"workers must be at least 1 (got {workers})")
    camera = camera or Camera.preset("nyu")
    options = options or SceneOptions()
    root = Path(out_dir)
    root.mkdir(parents=True, exist_ok=True)
    names = [frame_name(i) for i in range(count)]
    done = 0
    if workers == 1:
        for i in range(count):
            _make_frame(str(root), seed, i, camera, options)
            done += 1
            if progress:
                progress(done)
    else:
        # one ray-casting thread per process: the processes already fill the cores
        worker_options = replace(options, threads=1)
        with ProcessPoolExecutor(max_workers=workers, mp_context=get_context("spawn")) as pool:
            futures = [
                pool.submit(_make_frame, str(root), seed, i, camera, worker_options) for i in range(count)
            ]
            for fut in as_completed(futures):
                fut.result()
                done += 1
                if progress:
                    progress(done)
    write_cameras(root, {n: camera for n in names}, depth_scale=DEPTH_SCALE)
    atomic_write_json(
        root / "splits.json", {s: [n for i, n in enumerate(names) if split_of(i) == s] for s in SPLITS}
    )
    atomic_write_json(
        root / "synth.json",
        {
            "generator": "cuboidcli.synth",
            "seed": seed,
            "count": count,
            "camera": camera.to_dict(),
            "options": options.to_dict(),
            "split_rule": "index % 10: 0-7 train, 8 val, 9 test",
        },
    )
    return names

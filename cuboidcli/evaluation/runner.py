"""Evaluate a dataset: fit (or load) cuboids per frame, compute the metrics, repeat over seeds, write outputs.

Every frame is fitted independently with ``config.seed`` = the run's seed, so a frame's result does not
depend on the order of frames or on the process that evaluates it: ``workers > 1`` spreads frames over
processes, ``ray`` over Ray tasks (:mod:`cuboidcli.scaleout`), and both give the same numbers as
``workers = 1`` (see :func:`evaluate`). A frame that fails is reported in the report's ``failed`` and left
out of the aggregates; the others go on.
"""

from __future__ import annotations

import os
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Protocol

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.aggregate import aggregate, mean_std
from cuboidcli.evaluation.auc import AUC_CM
from cuboidcli.evaluation.fits import fit_and_save, reusable_fit, saved_fit_path
from cuboidcli.evaluation.metrics import FrameMetrics, frame_metrics
from cuboidcli.evaluation.provenance import weights_hashes
from cuboidcli.evaluation.shape import Reference, gravity_from_saved, synthetic_reference
from cuboidcli.fitting.config import FitConfig
from cuboidcli.io.dataset import read_splits
from cuboidcli.io.depth import InputError
from cuboidcli.io.result import read_result
from cuboidcli.scaleout import Outcome, Summary, failed, run_tasks


class EvalFrame(Protocol):
    """What the runner needs of a frame (:class:`~cuboidcli.io.dataset.Frame`, :class:`.nyu.NyuFrame`)."""

    name: str
    camera: Camera

    def depth_m(self) -> np.ndarray: ...

    def gt_cuboids(self) -> list[Cuboid] | None: ...

    # optional: ``instances() -> np.ndarray | None``, per-pixel object ids (H, W), 0 = no object
    # optional: ``gt_world_from_camera() -> np.ndarray | None``, the known z-up world pose (synthetic data)


def _known_gravity(frame: EvalFrame) -> Reference | None:
    """The frame's true up vector and room axes where it has them (synthetic frames), else None."""
    read = getattr(frame, "gt_world_from_camera", None)
    pose = read() if callable(read) else None
    return None if pose is None else synthetic_reference(pose)


def _instances(frame: EvalFrame) -> np.ndarray | None:
    """The frame's instance image if it has one (synthetic data), checked against its camera."""
    read = getattr(frame, "instances", None)
    if not callable(read):
        return None
    inst = read()
    if inst is not None and inst.shape != (frame.camera.height, frame.camera.width):
        raise InputError(
            f"frame {frame.name}: instance image is {inst.shape[1]}x{inst.shape[0]} but its camera "
            f"is {frame.camera.width}x{frame.camera.height}"
        )
    return inst


@dataclass(frozen=True)
class EvalSettings:
    """How to evaluate. Thresholds in cm; seeds of the runs are seed, seed + 1, ..., seed + runs - 1."""

    auc_cm: tuple[float, ...] = AUC_CM
    runs: int = 1
    seed: int = 0
    workers: int = 1
    save_fits_dir: Path | None = None
    """Write each frame's cuboids as "cuboids/1" JSON to <dir>/seed<seed>/<frame>.json."""
    fits_dir: Path | None = None
    """Evaluate the saved fits <dir>/<frame>.json instead of fitting (one run)."""
    weights_dir: Path | None = None
    """Folder of the learned sampler / neural solver weights; None = the estimator's default."""
    rgb: bool = False
    """Fit from each frame's RGB image through a depth estimator (scored against the true depth)."""
    depth_model: Path | None = None
    """With ``rgb``: the depth network (.pt of the built-in net or .onnx, metric); None = the shipped one."""
    ray: str | None = None
    """Run the frames as Ray tasks: "" = on a Ray started for this run (``workers`` CPUs), else the
    address of a cluster ("auto", "ray://host:10001"); None = no Ray (``workers`` local processes)."""
    skip_existing: bool = True
    """With ``save_fits_dir``: a frame whose saved fit exists and was made with the same settings is scored
    from that file instead of being fitted again (an interrupted evaluation resumes)."""

    @property
    def seeds(self) -> list[int]:
        return [self.seed] if self.fits_dir is not None else [self.seed + r for r in range(self.runs)]


@dataclass
class ProgressEvent:
    """Sent after each frame: run index (0-based), frames done / total in this run, running aggregates."""

    run: int
    runs: int
    done: int
    total: int
    frame: str
    running: dict


@dataclass
class EvalReport:
    config: FitConfig
    settings: EvalSettings
    seeds: list[int]
    frames: list[list[FrameMetrics]]
    """Per run, in the order of the input frames."""
    runs: list[dict] = field(default_factory=list)
    """Aggregates per run (:func:`.metrics.aggregate`)."""
    summary: dict[str, tuple[float, float]] = field(default_factory=dict)
    """Mean and std over runs of every aggregate."""
    weights: dict[str, dict] = field(default_factory=dict)
    failures: list[dict] = field(default_factory=list)
    """Frames that could not be evaluated: {"run", "seed", "frame", "error"}; left out of the metrics."""
    counts: Summary = field(default_factory=Summary)
    """Frames (over all runs) fitted, scored from their saved fit (skipped), failed."""


def load_frames(
    data: str | os.PathLike,
    split: str | None = None,
    names: Sequence[str] | None = None,
    limit: int | None = None,
) -> tuple[list[EvalFrame], dict]:
    """Frames of a dataset and a description of it: (frames, {"path", "format", "split"}).

    ``data`` is a folder holding the official NYU Depth v2 files (split defaults to test), or a folder in the
    generic layout of :mod:`cuboidcli.io.dataset` (split from its splits.json; default all frames).
    ``names`` keeps those frames (in the given order), then ``limit`` keeps the first ones.
    """
    from cuboidcli.evaluation.nyu import is_nyu_folder, list_nyu_frames
    from cuboidcli.io.dataset import list_frames

    if is_nyu_folder(data):
        split = split or "test"
        frames: list = list_nyu_frames(data, split)
        fmt = "nyu_depth_v2_labeled"
    else:
        frames = list_frames(data, split)
        frames = sorted(frames + _missing_split_frames(Path(data), split, frames), key=lambda f: f.name)
        fmt = "folder"
    if names:
        by_name = {f.name: f for f in frames}
        missing = [n for n in names if n not in by_name]
        if missing:
            some = ", ".join(list(by_name)[:5])
            raise InputError(
                f"--frames: no frame named {missing[0]!r} in {data}"
                f"{f' (split {split})' if split else ''}; frames are e.g. {some}"
            )
        frames = [by_name[n] for n in names]
    if limit is not None:
        if limit < 1:
            raise InputError(f"--limit {limit}: give a positive number of frames")
        frames = frames[:limit]
    return frames, {
        "path": str(Path(data).resolve()),
        "format": fmt,
        "split": split,
        "frames": [f.name for f in frames],
    }


def _missing_split_frames(root: Path, split: str | None, frames: list) -> list[MissingFrame]:
    """Frames that the split of ``splits.json`` names but the folder has no depth map for."""
    if split is None:
        return []
    have = {f.name for f in frames}
    names = read_splits(root).get(split, [])
    return [MissingFrame(str(n), root) for n in dict.fromkeys(names) if str(n) not in have]


def check_estimator(config: FitConfig, weights_dir: Path | None = None) -> None:
    """Build the configured solver and sampler once, so that a bad setting or missing weights fails before
    any frame is evaluated (raises InputError with a one-line message)."""
    from cuboidcli.factories import make_sampler, make_solver

    try:
        make_solver(config, weights_dir, None, config.device)
        make_sampler(config.sampler, weights_dir, config.device)
    except (ValueError, FileNotFoundError, ImportError) as e:
        raise InputError(f"cannot run sampler {config.sampler!r} with solver {config.solver!r}: {e}") from e


def evaluate_frame(
    frame: EvalFrame,
    config: FitConfig,
    auc_cm: Sequence[float],
    save_fits_dir: Path | None = None,
    fits_dir: Path | None = None,
    weights_dir: Path | None = None,
    rgb: bool = False,
    depth_model: Path | None = None,
) -> FrameMetrics:
    """Fit (or load from ``fits_dir``) the cuboids of one frame and compute its metrics.

    Besides the paper's metrics: the parsimony curve up to ``config.max_cuboids``; where the frame has
    an instance image, object recall / precision with ``config``'s point-to-cuboid assignment (for saved
    fits, the settings recorded in the file take precedence: :func:`_scoring_config`); the shape
    measurements (axis angles against the fit's gravity, else the frame's known one, else one estimated
    from its depth; support; the gravity error where the gravity is known: :mod:`.shape`).
    Time is the estimator's ``timing_s["total"]`` (input loaded -> cuboids selected; metrics excluded),
    or the saved file's when evaluating saved fits. With ``rgb`` the cuboids are fitted to the depth
    estimated from the image and scored against the frame's true depth.
    """
    depth = frame.depth_m()
    if depth.shape != (frame.camera.height, frame.camera.width):
        raise InputError(
            f"frame {frame.name}: depth map is {depth.shape[1]}x{depth.shape[0]} but its camera "
            f"is {frame.camera.width}x{frame.camera.height}"
        )
    if fits_dir is not None:
        path = Path(fits_dir) / f"{frame.name}.json"
        try:
            saved = read_result(path)
        except (FileNotFoundError, ValueError, KeyError) as e:
            raise InputError(f"frame {frame.name}: cannot read saved fit {path}: {e}") from e
        cuboids, timing = saved.cuboids, saved.timing_s
        config = _scoring_config(config, saved.settings if isinstance(saved.settings, dict) else {})
        gravity = gravity_from_saved(saved.extras.get("gravity"))
    else:
        cuboids, timing, gravity = fit_and_save(
            frame, depth, config, weights_dir, save_fits_dir, rgb, depth_model
        )
    total = timing.get("total")
    return frame_metrics(
        frame.name,
        depth,
        frame.camera,
        cuboids,
        auc_cm=tuple(auc_cm),
        gt=frame.gt_cuboids(),
        time_s=None if total is None else float(total),
        parsimony_k=config.max_cuboids,
        instances=_instances(frame),
        config=config,
        shape=True,
        fit_gravity=gravity,
        known_gravity=_known_gravity(frame),
    )


#: Settings of a saved fit that its scoring uses (parsimony length, the point-to-cuboid assignment, and the
#: grid step and seed of the gravity estimate of a fit that had none).
_SCORING_SETTINGS = (
    "max_cuboids",
    "tau_sq_m2",
    "beta",
    "tau_c_sq_m2",
    "occlusion_aware",
    "grid_step",
    "seed",
)


def _scoring_config(config: FitConfig, saved_settings: dict) -> FitConfig:
    """``config`` with the scoring settings of a saved fit where its file records them (files written by
    ``cuboids fit`` / ``evaluate --save-fits`` do), so that re-scoring saved fits gives the same numbers."""
    over: dict = {}
    for key in _SCORING_SETTINGS:
        if key not in saved_settings:
            continue
        value = saved_settings[key]
        if key in ("max_cuboids", "grid_step") and isinstance(value, int) and not isinstance(value, bool):
            if value >= 1:
                over[key] = value
        elif key == "seed" and isinstance(value, int) and not isinstance(value, bool):
            over[key] = value
        elif key == "occlusion_aware" and isinstance(value, bool):
            over[key] = value
        elif key in ("tau_sq_m2", "beta") and isinstance(value, int | float) and value > 0:
            over[key] = float(value)
        elif key == "tau_c_sq_m2" and (value is None or (isinstance(value, int | float) and value > 0)):
            over[key] = None if value is None else float(value)
    return replace(config, **over) if over else config


def evaluate_task(
    frame: EvalFrame,
    config: FitConfig,
    auc_cm: Sequence[float],
    settings: EvalSettings,
) -> Outcome:
    """One frame of one run, as a task of :func:`cuboidcli.scaleout.run_tasks`: its metrics in ``value``;
    "skipped" when it was scored from the fit a previous run saved; "failed" with the one-line reason."""
    try:
        if settings.save_fits_dir is not None and settings.skip_existing:
            path = saved_fit_path(settings.save_fits_dir, config.seed, frame.name)
            if reusable_fit(path, config, settings.weights_dir):
                m = evaluate_frame(frame, config, auc_cm, fits_dir=path.parent)
                return Outcome(frame.name, "skipped", value=m)
        m = evaluate_frame(
            frame,
            config,
            auc_cm,
            settings.save_fits_dir,
            settings.fits_dir,
            settings.weights_dir,
            settings.rgb,
            settings.depth_model,
        )
    except Exception as e:  # this frame fails; the evaluation goes on
        return failed(frame.name, e)
    return Outcome(frame.name, "done", value=m)


@dataclass(frozen=True)
class MissingFrame:
    """A frame that ``splits.json`` lists but the dataset has no depth map for: evaluating it fails."""

    name: str
    root: Path
    camera: None = None

    def depth_m(self) -> np.ndarray:
        raise InputError(f"frame {self.name} is listed in {self.root / 'splits.json'} but has no depth map")


def evaluate(
    frames: Sequence[EvalFrame],
    config: FitConfig,
    settings: EvalSettings,
    progress: Callable[[ProgressEvent], None] | None = None,
    on_failed: Callable[[int, Outcome], None] | None = None,
) -> EvalReport:
    """Evaluate ``frames`` once per seed; returns per-frame metrics, per-run aggregates and mean/std.

    The frames of every run go to the engine together (``settings.workers``, ``settings.ray``).
    ``on_failed(run, outcome)`` hears of each failed frame as it fails. Raises InputError when no frame
    of a run could be evaluated."""
    if not frames:
        raise InputError("no frames to evaluate (check --split, --frames and --limit)")
    from cuboidcli.weights import check_weights_option, default_weights_dir

    config = config.for_kind("frame")  # the frames' defaults for what was left unset (parsimony's K)

    if settings.fits_dir is None:
        check_weights_option(settings.weights_dir, config.solver, config.sampler)
    if settings.weights_dir is None:  # the shipped bundle that matches the input and the solver
        bundle = default_weights_dir(config.solver, settings.rgb, settings.depth_model is None)
        settings = replace(settings, weights_dir=bundle)
    if settings.fits_dir is None:
        check_estimator(config, settings.weights_dir)
    seeds = settings.seeds
    report = EvalReport(config=config, settings=settings, seeds=seeds, frames=[])
    tasks = [
        (frame, replace(config, seed=seed), tuple(settings.auc_cm), settings)
        for seed in seeds
        for frame in frames
    ]
    names = [f"{frame.name} (seed {seed})" for seed in seeds for frame in frames]
    results: list[dict[int, FrameMetrics]] = [{} for _ in seeds]
    failures: list[dict[int, str]] = [{} for _ in seeds]

    def on_result(k: int, outcome: Outcome) -> None:
        r, i = divmod(k, len(frames))
        report.counts.add(outcome)
        if outcome.status == "failed":
            failures[r][i] = outcome.message
            if on_failed is not None:
                on_failed(r, outcome)
        else:
            results[r][i] = outcome.value
        if progress is not None:
            running = aggregate(list(results[r].values()), curves=False) if results[r] else {}
            done = len(results[r]) + len(failures[r])
            progress(ProgressEvent(r, len(seeds), done, len(frames), outcome.name, running))

    run_tasks(evaluate_task, tasks, names, workers=settings.workers, ray=settings.ray, on_result=on_result)
    for r, seed in enumerate(seeds):
        report.failures += [
            {"run": r, "seed": seed, "frame": frames[i].name, "error": failures[r][i]}
            for i in sorted(failures[r])
        ]
        ordered = [results[r][i] for i in range(len(frames)) if i in results[r]]
        if not ordered:
            first = report.failures[0]
            others = len({f["frame"] for f in report.failures}) - 1
            raise InputError(first["error"] + (f" (and {others} more frames failed)" if others else ""))
        report.frames.append(ordered)
        report.runs.append({**aggregate(ordered), "frames_failed": len(failures[r])})
    report.summary = mean_std(report.runs)
    report.weights = weights_hashes(config, settings.weights_dir)
    return report

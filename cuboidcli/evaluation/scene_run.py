"""Room scans scored room by room: the library side of ``cuboids evaluate DIR`` on a folder of scans.

A room scan is a folder in the plain sequence layout with its ground truth, as
:func:`cuboidcli.synth.scan.write_room_scan` writes it (``cuboids synth --views N`` writes
``OUT/scene_0000/`` ...): ``gt.json`` (world-frame cuboids, z up, metres) and ``truth_points.npz``
(evaluation points with instance ids). Every scan is fitted as ``cuboids fit FOLDER`` fits it
(:meth:`cuboidcli.api.Fitter.fit`), or, with ``bare``, its fused points are fitted as a bare cloud
without the cameras; optionally the Open3D planes + clusters baseline (:mod:`.baseline`) is fitted to the
same fused points. Each fit is scored by :func:`.scene.scene_metrics` and the rows of a method are
aggregated over the rooms by :func:`.scene.aggregate_scenes`.
"""

from __future__ import annotations

import math
import os
import time
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cuboidcli.evaluation.scene import aggregate_scenes, scene_metrics

#: The files that make a folder a room scan with ground truth.
SCAN_FILES = ("gt.json", "truth_points.npz")
#: Room scans inside a folder are its subfolders named with this prefix (``scene_0000``, ...).
SCENE_PREFIX = "scene_"
#: Method ids of the rows: the estimator, and the Open3D planes + clusters baseline.
FITTED, BASELINE = "cuboids", "baseline"
BASELINE_LABEL = "open3d planes+clusters"
#: Row keys that name a row rather than measure it (left out of the aggregates).
ID_KEYS = ("scene", "method")

#: ``progress(done, total, what)``: ``done`` rooms of ``total`` are finished; ``what`` is being done now.
SceneProgress = Callable[[int, int, str], None]


def is_room_scan(path: str | os.PathLike) -> bool:
    """Whether ``path`` is a folder holding a room scan's ground truth (:data:`SCAN_FILES`)."""
    p = Path(path)
    return p.is_dir() and all((p / name).is_file() for name in SCAN_FILES)


def scan_candidates(root: str | os.PathLike) -> list[Path]:
    """The folders of ``root`` meant as room scans, complete or not: ``root`` itself when it holds a
    ``gt.json``, else its ``scene_*`` subfolders (sorted by name); empty when there are none."""
    root = Path(root)
    if not root.is_dir():
        return []
    if (root / SCAN_FILES[0]).is_file():
        return [root]
    return sorted(p for p in root.iterdir() if p.name.startswith(SCENE_PREFIX) and p.is_dir())


def scene_folders(root: str | os.PathLike) -> list[Path]:
    """The complete room scans of ``root`` (:func:`scan_candidates` that pass :func:`is_room_scan`)."""
    return [p for p in scan_candidates(root) if is_room_scan(p)]


@dataclass(frozen=True)
class SceneEvalSettings:
    """How the rooms are fitted (the room settings, visibility, voxel, max_cuboids, are the Fitter's):
    ``bare`` fits the fused points without their cameras (as a point cloud file would be), ``baseline``
    also scores the Open3D planes + clusters baseline."""

    bare: bool = False
    baseline: bool = False

    def to_dict(self) -> dict:
        return {"bare": self.bare, "baseline": self.baseline}


@dataclass
class SceneEvalReport:
    """The rows of an evaluation (one per room and method: ``scene``, ``method``, the metrics of
    :func:`.scene.scene_metrics` and ``seconds``, the fit's wall time without reading and fusing the
    scan), the methods' labels (id -> label, in table order) and their aggregates over the rooms
    (:func:`.scene.aggregate_scenes`: pooled recalls and precisions, mean AUC, mean seconds)."""

    rows: list[dict]
    labels: dict[str, str]
    aggregate: dict[str, dict]

    def to_dict(self) -> dict:
        return {"methods": self.labels, "aggregate": self.aggregate, "scenes": self.rows}


def _fit(folder: Path, fitter, settings: SceneEvalSettings):
    """Fit one scan through :meth:`~cuboidcli.api.Fitter.fit`: (fused points (N, 3), cuboids, object boxes,
    visibility used, seconds of the fit alone)."""
    from cuboidcli.load import load

    inp = load(folder)
    t = time.perf_counter()
    # reading and fusing the frames is the same for every method: left out of the fit's time; with
    # ``bare`` the fused points alone, as a .ply of them would be read: no cameras, no up hint
    res = fitter.fit(inp.points) if settings.bare else fitter.fit_input(inp)
    seconds = time.perf_counter() - t
    return inp.points, res.cuboids, res.objects, res.info.visibility, seconds


def _scan_up(folder: Path) -> np.ndarray:
    """(3,) the scan's up direction as its ground truth records it (z for the synthetic scans)."""
    from cuboidcli.io.result import read_result

    return np.asarray(read_result(folder / "gt.json").extras.get("up", [0.0, 0.0, 1.0]), dtype=np.float64)


def evaluate_scene(
    folder: str | os.PathLike,
    fitter,
    settings: SceneEvalSettings,
    progress: Callable[[str], None] | None = None,
) -> tuple[list[dict], str]:
    """Fit and score one room scan: (its rows, the fitted method's visibility). ``fitter`` is a
    :class:`cuboidcli.api.Fitter`; ``progress(what)`` is told each step. Raises InputError for an
    unreadable scan."""
    import zipfile

    from cuboidcli.io.depth import InputError
    from cuboidcli.synth.scan import read_scan_truth

    folder = Path(folder)
    try:
        gt, points, instance = read_scan_truth(folder)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile) as e:  # a file cut short or of another kind
        raise InputError(f"{folder}: cannot read its ground truth ({type(e).__name__}: {e})") from e
    if progress:
        progress("fitting")
    fused, cuboids, objects, visibility, seconds = _fit(folder, fitter, settings)
    name = folder.name
    metrics = scene_metrics(cuboids, gt, points, instance, objects=objects)
    rows = [{"scene": name, "method": FITTED, **metrics, "seconds": seconds}]
    if settings.baseline:
        from cuboidcli.evaluation.baseline import planes_and_clusters

        if progress:
            progress("baseline")
        t = time.perf_counter()
        # the baseline is told the true up; the estimator finds it from the points
        boxes = planes_and_clusters(fused, up=_scan_up(folder))
        seconds = time.perf_counter() - t
        rows.append(
            {
                "scene": name,
                "method": BASELINE,
                **scene_metrics(boxes, gt, points, instance),
                "seconds": seconds,
            }
        )
    return rows, visibility


def fitted_label(visibility: str, bare: bool) -> str:
    """The estimator's row label: its visibility and whether the cameras were dropped."""
    return f"cuboids ({visibility}{', bare cloud' if bare else ''})"


def evaluate_scenes(
    folders: list[Path], fitter, settings: SceneEvalSettings, progress: SceneProgress | None = None
) -> SceneEvalReport:
    """Fit and score every room scan of ``folders`` in order (:func:`evaluate_scene`) and aggregate each
    method over the rooms. ``progress(done, total, what)`` before each step and once at the end."""
    rows: list[dict] = []
    visibility = fitter.config.visibility
    for i, folder in enumerate(folders):

        def step(what: str, done: int = i, name: str = folder.name) -> None:
            if progress is not None:
                progress(done, len(folders), f"{name}: {what}")

        scene_rows, visibility = evaluate_scene(folder, fitter, settings, step)
        rows.extend(scene_rows)
    if progress:
        progress(len(folders), len(folders), "done")
    labels = {FITTED: fitted_label(visibility, settings.bare)}
    if settings.baseline:
        labels[BASELINE] = BASELINE_LABEL
    aggregate = {
        m: aggregate_scenes(
            [{k: v for k, v in r.items() if k not in ID_KEYS} for r in rows if r["method"] == m]
        )
        for m in labels
    }
    return SceneEvalReport(rows, labels, aggregate)


def json_safe(obj):
    """A copy for strict JSON: NaN and inf become null, numpy scalars Python numbers, tuples lists."""
    if isinstance(obj, dict):
        return {str(k): json_safe(v) for k, v in obj.items()}
    if isinstance(obj, list | tuple):
        return [json_safe(v) for v in obj]
    if isinstance(obj, np.generic):
        obj = obj.item()
    if isinstance(obj, float) and not math.isfinite(obj):
        return None
    return obj


def write_report(path: str | os.PathLike, schema: str, body: dict, provenance: dict) -> Path:
    """Write an evaluation's ``body`` with its ``provenance`` (command, data, settings, ...), the package
    version, the ``schema`` name and the machine to ``path`` as JSON, atomically (a run killed while writing
    leaves the previous file or none, never half of one); NaN (a ratio of nothing) and inf as null."""
    from cuboidcli import __version__
    from cuboidcli.evaluation.provenance import machine_info
    from cuboidcli.io.atomic import atomic_write_json

    doc = {"schema": schema, "version": __version__, **provenance, **body, "machine": machine_info()}
    return atomic_write_json(path, json_safe(doc))


def write_scene_report(path: str | os.PathLike, report: SceneEvalReport, provenance: dict) -> Path:
    """Write ``report`` and ``provenance`` (version, command, settings, ...) to ``path``
    (:func:`write_report`, schema ``cuboids-scenes/1``)."""
    return write_report(path, "cuboids-scenes/1", report.to_dict(), provenance)

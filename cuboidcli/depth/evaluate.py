"""Depth errors of an estimator on a dataset folder (the layout of :func:`cuboidcli.io.dataset.list_frames`).

Per frame: AbsRel, RMSE (m) and delta < 1.25 over the valid ground-truth pixels (raw depth: holes excluded,
no crop, no depth cap), then their means over frames. In flat folders that hold both ``<name>_depth_raw``
and ``<name>_depth_filled``, the raw map is the ground truth by default: in-painted depth is itself an
estimate. ``python -m cuboidcli.cli.depth_evaluate DATA`` prints them.
"""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

from cuboidcli.depth.metrics import depth_errors, mean_errors
from cuboidcli.io.dataset import DEPTH_SUFFIXES, Frame, list_frames


def evaluate_frames(estimator, frames: list[Frame]) -> dict:
    """Errors of ``estimator`` (a DepthEstimator) on frames with RGB images:
    ``{"frames": {name: {"abs_rel", "rmse_m", "delta1", "valid_px"}}, "mean": {...}}``."""
    per = {}
    for f in frames:
        rgb = f.rgb()
        if rgb is None:
            raise ValueError(f"frame {f.name} has no RGB image")
        per[f.name] = depth_errors(estimator.predict(rgb, f.camera), f.depth_m())
    return {"frames": per, "mean": mean_errors(list(per.values()))}


def with_raw_depth(frames: list[Frame]) -> list[Frame]:
    """Swap an in-painted ``<name>_depth_filled`` ground truth for its ``<name>_depth_raw`` sibling."""
    out = []
    for f in frames:
        if f.depth_path.stem.endswith("_depth_filled"):
            for suffix in DEPTH_SUFFIXES:
                raw = f.depth_path.with_name(f"{f.name}_depth_raw{suffix}")
                if raw.is_file():
                    f = replace(f, depth_path=raw)
                    break
        out.append(f)
    return out


def evaluate_dataset(estimator, root: str | Path, split: str | None = None, raw: bool = True) -> dict:
    """:func:`evaluate_frames` on the frames of ``root`` (optionally one split) that have RGB images."""
    frames = [f for f in list_frames(root, split) if f.rgb_path is not None]
    if raw:
        frames = with_raw_depth(frames)
    if not frames:
        raise ValueError(f"no frames with RGB images in {root}")
    report = evaluate_frames(estimator, frames)
    report["ground_truth"] = {f.name: f.depth_path.name for f in frames}
    return report

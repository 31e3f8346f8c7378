"""Training data of the sampling-weight network: dataset splits, fitting grids, input statistics, order.

Frames come from a dataset folder in the generic layout (:mod:`cuboidcli.io.dataset`); ``splits.json``
gives the train and val frames (``cuboids synth`` writes one). Without it every tenth frame is held out
for validation, and with fewer than ten frames all of them serve for both.
"""

from __future__ import annotations

import math
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from pathlib import Path

import torch

from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.fit_input import FitInput
from cuboidcli.fitting.prepare import prepare_points
from cuboidcli.io.dataset import Frame, list_frames, read_splits


@dataclass
class TrainScene:
    """A training frame reduced to its fitting points."""

    name: str
    prep: FitInput


def dataset_splits(root: str | Path) -> tuple[list[Frame], list[Frame], str]:
    """(train frames, val frames, how the split was made) of a dataset folder.

    A folder with the official NYU Depth v2 files (``nyu_depth_v2_labeled.mat`` + ``splits.mat``) gives the
    paper's split: train = the first 600 of the official training frames, val = the other 195.
    """
    from cuboidcli.evaluation.nyu import is_nyu_folder, list_nyu_frames

    root = Path(root)
    if is_nyu_folder(root):
        return list_nyu_frames(root, "train"), list_nyu_frames(root, "val"), "NYU Depth v2 splits.mat"
    frames = list_frames(root)
    splits = read_splits(root)
    if splits:
        train = [f for f in frames if f.name in set(splits.get("train", []))]
        val = [f for f in frames if f.name in set(splits.get("val", []))]
        if train:
            return train, val, "splits.json"
    if len(frames) < 10:
        return frames, frames, "all frames (fewer than 10: validation on the training frames)"
    val = frames[9::10]
    held = {f.name for f in val}
    return [f for f in frames if f.name not in held], val, "every tenth frame held out"


def prepare_scenes(
    frames: list[Frame], grid_step: int | FitConfig, min_points: int, workers: int = 1
) -> list[TrainScene]:
    """Read the frames and keep their fitting grids (frames with fewer than ``min_points`` are skipped).
    ``grid_step``: the grid's step, or a FitConfig whose ``step_for`` each frame's size gives it."""

    def one(frame: Frame) -> TrainScene:
        depth = frame.depth_m()
        step = grid_step.step_for(*depth.shape) if isinstance(grid_step, FitConfig) else grid_step
        return TrainScene(frame.name, prepare_points(depth, frame.camera, step).as_tensors())

    if workers > 1:
        with ThreadPoolExecutor(workers) as pool:
            scenes = list(pool.map(one, frames))
    else:
        scenes = [one(f) for f in frames]
    return [s for s in scenes if s.prep.points.shape[0] >= min_points]


def depth_statistics(scenes: list[TrainScene]) -> tuple[float, float]:
    """Mean and standard deviation (m) of the valid fitting-point depths: the input normalisation."""
    z = torch.cat([s.prep.points[:, 2].double() for s in scenes])
    return float(z.mean()), float(z.std().clamp_min(1e-3))


def epoch_order(n_scenes: int, epoch: int, seed: int, scenes_per_epoch: int | None = None) -> list[int]:
    """Scene indices of an epoch: random permutations, concatenated up to ``scenes_per_epoch`` (None = one
    pass). Depends only on (seed, epoch), so a resumed run sees the same order."""
    gen = torch.Generator().manual_seed(seed * 1_000_003 + epoch)
    count = scenes_per_epoch or n_scenes
    perms = [torch.randperm(n_scenes, generator=gen) for _ in range(math.ceil(count / n_scenes))]
    return torch.cat(perms)[:count].tolist()

"""The training state a run saves and resumes from (``last.pt`` and its snapshots): reading it, with the
keys of older files renamed, and the config a resumed trainer goes on with."""

from __future__ import annotations

from collections.abc import Iterable
from dataclasses import replace
from pathlib import Path
from typing import TypeVar

import torch

from cuboidcli.io.checkpoints import read_checkpoint
from cuboidcli.learn.distributed import state_sha256

LAST = "last.pt"
"""The training state a run resumes from."""

#: Keys of the training states written before this loop, and the names they have now.
LEGACY_STATE_KEYS = {"iteration": "step", "best_msd_m2": "best", "best_abs_rel": "best", "rng": "torch_rng"}

Config = TypeVar("Config")


def read_state(path: str | Path, kind: str, what: str, hint: str = LAST) -> dict:
    """The training state stored at ``path``, with the keys of older files renamed
    (:data:`LEGACY_STATE_KEYS`); ValueError naming ``what`` and ``hint`` when it holds something else."""
    state = read_checkpoint(path)
    if state.get("kind") != kind:
        raise ValueError(f"{path} is not a {what} checkpoint (use {hint})")
    for old, new in LEGACY_STATE_KEYS.items():
        if old in state and new not in state:
            state[new] = state.pop(old)
    return state


def resumed(
    resume: str | Path | None,
    given: Config,
    keep: Iterable[str],
    kind: str,
    what: str,
    hint: str = LAST,
    key: str = "train_config",
) -> tuple[dict | None, Config]:
    """What a trainer called with ``resume`` goes on from: the training state stored there
    (:func:`read_state` of ``kind``, ``what`` and ``hint``) and the config of the checkpoint (its entry
    ``key``, a dict of the dataclass type of ``given``) with the fields ``keep`` taken from ``given``.
    A fresh run (``resume`` None): None and ``given``."""
    if resume is None:
        return None, given
    state = read_state(resume, kind, what, hint)
    return state, replace(type(given)(**state[key]), **{k: getattr(given, k) for k in keep})


def params_sha256(networks: dict[str, torch.nn.Module]) -> str:
    """One hash of the networks' weights (:func:`~cuboidcli.learn.distributed.state_sha256`): of the
    state dict of a single network, of the names prefixed by the network's name for several."""
    if len(networks) == 1:
        return state_sha256(next(iter(networks.values())).state_dict())
    return state_sha256({f"{k}.{n}": t for k, m in networks.items() for n, t in m.state_dict().items()})

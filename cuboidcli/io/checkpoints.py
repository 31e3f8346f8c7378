"""Reading the tool's weights files, with one clear error for every way a file can be wrong.

Every network of the tool (sampling-weight network, neural solver, depth network) is stored as a plain dict
``{"config": dict, "state_dict": {name: tensor}, "meta": dict}`` and read with
``torch.load(weights_only=True)``, which refuses a file whose pickle would build arbitrary Python objects
(and so could run code). This module is the one place that reads such files: every loader calls
:func:`load_net` (or :func:`read_checkpoint` for training states), and every problem becomes a
:class:`CheckpointError` with a one-line message naming the file and what to pass instead:

- the file is missing, empty, truncated, or not a PyTorch file at all (a zip or text file of another tool);
- its pickle holds objects besides tensors and plain containers (refused, never executed);
- it is a PyTorch file but not one of ours (no ``config`` / ``state_dict``);
- it holds another kind of network (a sampler file given where the solver is expected);
- its tensors do not fit the network its config describes (renamed, missing or reshaped parameters).
"""

from __future__ import annotations

import os
import re
from collections.abc import Callable
from pathlib import Path
from typing import TypeVar

from cuboidcli.io.depth import InputError

#: A config key that only each kind of network has (how a file tells what it holds).
KIND_KEYS = {"sampler": "maps", "solver": "heads", "depth": "channels"}

#: What writes each kind, for the messages.
_WRITERS = {
    "sampler": "cuboids train sampler",
    "solver": "cuboids train solver",
    "depth": "cuboids train depth",
}

Net = TypeVar("Net")


class CheckpointError(InputError):
    """A weights file that cannot be used; the message is one line naming the file and what to do."""


def _first_line(exc: BaseException, limit: int = 160) -> str:
    """The exception's message on one line (torch spreads its state-dict errors over several)."""
    text = " ".join(part.strip() for part in str(exc).splitlines() if part.strip()) or type(exc).__name__
    return text if len(text) <= limit else text[: limit - 3] + "..."


def _writer(kind: str | None) -> str:
    return _WRITERS.get(kind or "", "the cuboids trainers")


def read_checkpoint(path: str | os.PathLike, kind: str | None = None) -> dict:
    """The dict stored in a weights or training-state file, read with ``weights_only=True``.

    ``kind`` (sampler | solver | depth | None) only words the messages. Raises :class:`CheckpointError`.
    """
    import pickle

    import torch

    path = Path(path)
    what = f"{kind} weights" if kind else "checkpoint"
    if not path.is_file():
        raise CheckpointError(f"{what} {path} not found; pass a .pt file written by {_writer(kind)}")
    if path.stat().st_size == 0:
        raise CheckpointError(f"{what} {path} is an empty file; pass a .pt file written by {_writer(kind)}")
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except pickle.UnpicklingError as e:
        refused = re.search(r"Unsupported global: GLOBAL (\S+)", str(e))
        if refused:
            raise CheckpointError(
                f"{what} {path} holds a Python object ({refused.group(1)}) besides tensors; it was refused "
                f"without running it (a weights file of ours holds only tensors): pass a file written by "
                f"{_writer(kind)}"
            ) from e
        raise CheckpointError(
            f"cannot read {what} {path}: it is truncated or not a PyTorch file (the pickle is invalid); "
            "download or train it again"
        ) from e
    except Exception as e:  # torch raises RuntimeError, OSError, EOFError, KeyError... for foreign bytes
        raise CheckpointError(
            f"cannot read {what} {path}: it is truncated or not a PyTorch file ({type(e).__name__}: "
            f"{_first_line(e)}); download or train it again"
        ) from e
    if not isinstance(ckpt, dict):
        raise CheckpointError(
            f"{what} {path} holds a {type(ckpt).__name__}, not the dict a weights file of ours holds; "
            f"pass a file written by {_writer(kind)}"
        )
    return ckpt


def checkpoint_kind(ckpt: dict) -> str | None:
    """ "sampler", "solver" or "depth" for a network dict of ours (by its config keys), else None."""
    config = ckpt.get("config")
    if not isinstance(config, dict) or not isinstance(ckpt.get("state_dict"), dict):
        return None
    return next((kind for kind, key in KIND_KEYS.items() if key in config), None)


def load_net(path: str | os.PathLike, kind: str, build: Callable[[dict], Net]) -> Net:
    """Read the network of ``kind`` stored at ``path`` and rebuild it with ``build(ckpt)``.

    ``build`` is the kind's ``net_from_checkpoint`` (config -> module, then ``load_state_dict``). Raises
    :class:`CheckpointError` for every problem listed in the module docstring.
    """
    ckpt = read_checkpoint(path, kind)
    found = checkpoint_kind(ckpt)
    if found is None:
        raise CheckpointError(
            f"{kind} weights {path} is a PyTorch file but not a network of this tool (no 'config' and "
            f"'state_dict'); pass a file written by {_writer(kind)}"
        )
    if found != kind:
        raise CheckpointError(
            f"{kind} weights {path} holds the {found} network, not the {kind} network; pass the "
            f"{kind} file (written by {_writer(kind)}) or the folder that holds both"
        )
    try:
        return build(ckpt)
    except (RuntimeError, ValueError, TypeError, KeyError, AttributeError) as e:
        raise CheckpointError(
            f"{kind} weights {path} do not fit the network their config describes ({_first_line(e)}); "
            "the file is damaged or from an incompatible version: train it again"
        ) from e

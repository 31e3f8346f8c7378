"""Where an evaluation's numbers come from: the weights files it loaded (path and SHA-256) and the machine
it ran on (timings depend on it)."""

from __future__ import annotations

import hashlib
import os
from pathlib import Path

import numpy as np

from cuboidcli.fitting.config import FitConfig


def _sha256(path: Path) -> str:
    return hashlib.sha256(path.read_bytes()).hexdigest()


def weights_hashes(config: FitConfig, weights: Path | None) -> dict[str, dict]:
    """Path and SHA-256 of every weights file the configuration loads (neural solver, learned sampler).

    ``weights`` is what ``--weights`` gave (a folder or a file), None for the shipped defaults.
    """
    from cuboidcli.weights import files_loaded

    loaded = files_loaded(config.solver, config.sampler, weights)
    files = {kind if kind == "solver" else f"{kind}:{p.name}": p for kind, p in loaded.items()}
    return {role: {"path": str(p), "sha256": _sha256(p)} for role, p in files.items() if p.is_file()}


def machine_info() -> dict:
    """Where the numbers were measured (timings depend on it)."""
    import platform

    import numba
    import torch

    return {
        "platform": platform.platform(),
        "python": platform.python_version(),
        "processor": platform.processor() or platform.machine(),
        "cpu_count": os.cpu_count(),
        "torch": torch.__version__,
        "torch_threads": torch.get_num_threads(),
        "cuda": torch.cuda.get_device_name(0) if torch.cuda.is_available() else None,
        "numpy": np.__version__,
        "numba": numba.__version__,
    }

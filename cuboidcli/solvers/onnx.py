"""A CuboidSolver that runs an exported neural solver with onnxruntime (:class:`OnnxSolver`).

The graph maps ``minimal_sets`` (B, C, 3) float32, metres, to ``centers`` (B, 3), ``half_sizes`` (B, 3)
and ``rotations`` (B, 3, 3); B is a dynamic axis. The size bounds and the net's config travel in the
model's metadata. The export itself (``cuboids export --onnx``) is :mod:`cuboidcli.solvers.onnx_export`.
"""

from __future__ import annotations

import os
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from cuboidcli.solvers.base import SizeBounds
from cuboidcli.solvers.neural import CHUNK_SETS, check_bounds

INPUT = "minimal_sets"
OUTPUTS = ("centers", "half_sizes", "rotations")


class OnnxSolver:
    """CuboidSolver running an exported solver with onnxruntime on the CPU.

    ``minimal_sets`` (H, C, 3) m -> centers (H, 3), half_sizes (H, 3), rotations (H, 3, 3), in the input's
    dtype and device. ``bounds`` default to those stored in the model; other bounds are an error.
    ``threads``: chunks run concurrently in this many threads (default: torch's thread count), each
    single-threaded inside onnxruntime, for the reason given in :class:`NeuralSolver`.
    """

    name = "onnx"

    def __init__(
        self, onnx_path: str | os.PathLike, bounds: SizeBounds | None = None, threads: int | None = None
    ) -> None:
        try:
            import onnxruntime as ort
        except ImportError as e:  # optional dependency
            raise ImportError(
                "the ONNX solver needs onnxruntime (a dependency of cuboids): pip install onnxruntime"
            ) from e
        path = Path(onnx_path)
        if not path.is_file():
            raise FileNotFoundError(f"ONNX solver {path} not found; export one with cuboids export --onnx")
        options = ort.SessionOptions()
        options.intra_op_num_threads = 1
        options.inter_op_num_threads = 1
        self.threads = max(1, threads or torch.get_num_threads())
        self._pool = (
            ThreadPoolExecutor(self.threads, thread_name_prefix="onnx-solver") if self.threads > 1 else None
        )
        self.session = ort.InferenceSession(str(path), options, providers=["CPUExecutionProvider"])
        props = self.session.get_modelmeta().custom_metadata_map
        if "cuboids.a_min" not in props:
            raise ValueError(f"{path} is not a solver exported by cuboids (no size bounds in its metadata)")
        self.bounds = check_bounds(bounds, float(props["cuboids.a_min"]), float(props["cuboids.a_max"]))

    def _run_chunk(self, sets: np.ndarray) -> list[np.ndarray]:
        return self.session.run(list(OUTPUTS), {INPUT: sets})  # InferenceSession.run is thread-safe

    def warm_up(self) -> None:
        """Nothing to compile: onnxruntime's session is ready once loaded."""

    def __call__(self, minimal_sets: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        if minimal_sets.ndim != 3 or minimal_sets.shape[-1] != 3:
            raise ValueError(f"minimal_sets must be (H, C, 3), got {tuple(minimal_sets.shape)}")
        x = minimal_sets.detach().to("cpu", torch.float32).contiguous().numpy()
        # Chunked like the torch solver: small batches stay in the CPU cache.
        chunks = [x[i : i + CHUNK_SETS] for i in range(0, len(x), CHUNK_SETS)] or [x]
        run = self._run_chunk
        parts = list(self._pool.map(run, chunks)) if self._pool is not None else [run(c) for c in chunks]
        outs = [np.concatenate(p) for p in zip(*parts, strict=True)]
        return tuple(torch.from_numpy(o).to(minimal_sets.device, minimal_sets.dtype) for o in outs)


def build(inputs) -> OnnxSolver:
    """The solver of the parts registry (``onnx``) from a ``BuildInputs``: the exported solver
    ``inputs.onnx``, held to the fit's size bounds."""
    if inputs.onnx is None:
        raise ValueError("the onnx solver needs an ONNX file (--onnx solver.onnx)")
    return OnnxSolver(str(inputs.onnx), SizeBounds.of(inputs.config))

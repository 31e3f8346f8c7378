"""ONNX export of the neural cuboid solver and a CuboidSolver that runs it with onnxruntime.

The graph maps ``minimal_sets`` (B, C, 3) float32, metres, to ``centers`` (B, 3), ``half_sizes`` (B, 3)
and ``rotations`` (B, 3, 3); B is a dynamic axis. The opset is pinned (17 by default). The exporter is
PyTorch's TorchScript-based one (``dynamo=False``): the newer exporter needs the ``onnxscript`` package,
which the project does not depend on. Every export is checked against PyTorch with onnxruntime before
the file is moved into place. The size bounds and the net's config travel in the model's metadata.
"""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from concurrent.futures import ThreadPoolExecutor
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from cuboidcli.io.atomic import atomic_write
from cuboidcli.nets.solver import SolverNet
from cuboidcli.solvers.base import SizeBounds
from cuboidcli.solvers.neural import CHUNK_SETS, check_bounds, load_solver_net

INPUT = "minimal_sets"
OUTPUTS = ("centers", "half_sizes", "rotations")
#: Largest allowed |ONNX - PyTorch| difference of any output (metres, or rotation-matrix entries).
PARITY_TOL = 1e-4


def _parity_sets(c: int = 6) -> list[Tensor]:
    """Fixed check inputs: realistic synthetic sets (B = 64) and one single set (B = 1), float32."""
    from cuboidcli.solvers.synthetic import SyntheticConfig, seeded_batch

    data = SyntheticConfig(points=c)
    return [seeded_batch(64, data, seed=7).points, seeded_batch(1, data, seed=8).points]


def onnx_parity(net: SolverNet, onnx_path: str | os.PathLike, inputs: list[Tensor] | None = None) -> float:
    """Max |ONNX - PyTorch| over all outputs and the given (B, C, 3) inputs (default: fixed check sets)."""
    import onnxruntime as ort

    session = ort.InferenceSession(str(onnx_path), providers=["CPUExecutionProvider"])
    worst = 0.0
    net = net.eval()
    for x in inputs if inputs is not None else _parity_sets():
        x = x.float()
        with torch.inference_mode():
            ref = net(x)
        got = session.run(list(OUTPUTS), {INPUT: x.numpy()})
        for r, g in zip(ref, got, strict=True):
            worst = max(worst, float(np.abs(r.numpy() - g).max(initial=0.0)))
    return worst


def export_net_onnx(
    net: SolverNet, out_path: str | os.PathLike, opset: int = 17, meta: dict | None = None
) -> Path:
    """Export ``net`` to ``out_path`` (atomically), validated with onnxruntime; raises if parity > 1e-4."""
    import onnx

    net = net.to("cpu", torch.float32).eval()
    example = _parity_sets()[0][:8]
    axes = {name: {0: "sets"} for name in (INPUT, *OUTPUTS)}
    props = {
        "cuboids.solver_config": json.dumps(net.config.to_dict()),
        "cuboids.a_min": repr(net.config.a_min),
        "cuboids.a_max": repr(net.config.a_max),
        **{f"cuboids.{k}": str(v) for k, v in (meta or {}).items()},
    }

    def write(tmp: Path) -> None:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore", DeprecationWarning)  # the TorchScript exporter is "legacy"
            torch.onnx.export(
                net,
                (example,),
                str(tmp),
                dynamo=False,
                opset_version=opset,
                input_names=[INPUT],
                output_names=list(OUTPUTS),
                dynamic_axes=axes,
            )
        model = onnx.load(str(tmp))
        onnx.helper.set_model_props(model, props)
        onnx.checker.check_model(model)
        onnx.save(model, str(tmp))
        diff = onnx_parity(net, tmp)
        if not diff <= PARITY_TOL:
            raise RuntimeError(f"ONNX export does not match PyTorch: max abs difference {diff:.2e} > 1e-4")

    return atomic_write(out_path, write)


def export_solver_onnx(weights_path: str | os.PathLike, out_path: str, opset: int = 17) -> Path:
    """Export a solver weights file (``cuboids export --onnx`` passes ``models/solver_v2.pt`` by default) to
    ONNX; returns the path."""
    path = Path(weights_path)
    net = load_solver_net(path, "cpu")
    sha = hashlib.sha256(path.read_bytes()).hexdigest()
    return export_net_onnx(net, out_path, opset, meta={"weights": path.name, "weights_sha256": sha})


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
            raise FileNotFoundError(f"ONNX solver {path} not found; export one with export_solver_onnx()")
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

"""ONNX export of the neural cuboid solver (what ``cuboids export --onnx`` writes), checked for parity.

The graph is the one :class:`cuboidcli.solvers.onnx.OnnxSolver` runs (its module docstring has the
tensors). The opset is pinned (17 by default). The exporter is PyTorch's TorchScript-based one
(``dynamo=False``): the newer exporter needs the ``onnxscript`` package, which the project does not depend
on. Every export is checked against PyTorch with onnxruntime, on fixed synthetic minimal sets, before the
file is moved into place. The size bounds and the net's config travel in the model's metadata.
"""

from __future__ import annotations

import hashlib
import json
import os
import warnings
from pathlib import Path

import numpy as np
import torch
from torch import Tensor

from cuboidcli.io.atomic import atomic_write
from cuboidcli.nets.solver import SolverNet
from cuboidcli.solvers.neural import load_solver_net
from cuboidcli.solvers.onnx import INPUT, OUTPUTS

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

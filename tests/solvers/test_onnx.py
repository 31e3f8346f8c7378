"""ONNX export of the neural solver: pinned opset, dynamic batch, parity with PyTorch (tiny random nets)."""

from __future__ import annotations

import hashlib

import pytest
import torch

from cuboidcli.nets.checkpoint import checkpoint_dict
from cuboidcli.nets.solver import SolverNet, SolverNetConfig
from cuboidcli.solvers import onnx_export
from cuboidcli.solvers.base import SizeBounds
from cuboidcli.solvers.neural import NeuralSolver
from cuboidcli.solvers.onnx import OnnxSolver
from cuboidcli.solvers.onnx_export import export_net_onnx, export_solver_onnx, onnx_parity
from cuboidcli.solvers.synthetic import SyntheticConfig, seeded_batch

# The optional dependencies; cuboidcli.solvers.onnx and .onnx_export import them only when used.
onnx = pytest.importorskip("onnx")
pytest.importorskip("onnxruntime")

TINY = SolverNetConfig(width=16, layers=1, heads=2, ff=32)


pytestmark = pytest.mark.usefixtures("one_thread")


@pytest.fixture(scope="module")
def weights(tmp_path_factory):
    torch.manual_seed(0)
    path = tmp_path_factory.mktemp("weights") / "solver_tiny.pt"
    torch.save(checkpoint_dict(SolverNet(TINY), {"note": "test"}), path)
    return path


@pytest.fixture(scope="module")
def exported(weights, tmp_path_factory):
    return export_solver_onnx(str(weights), str(tmp_path_factory.mktemp("onnx") / "solver.onnx"))


def test_export_pins_opset_and_stores_metadata(weights, exported):
    model = onnx.load(str(exported))
    assert {o.domain: o.version for o in model.opset_import}[""] == 17
    props = {p.key: p.value for p in model.metadata_props}
    assert float(props["cuboids.a_max"]) == TINY.a_max
    assert props["cuboids.weights_sha256"] == hashlib.sha256(weights.read_bytes()).hexdigest()
    assert model.graph.input[0].type.tensor_type.shape.dim[0].dim_param == "sets"


@pytest.mark.parametrize("batch", [1, 37])
def test_parity_with_dynamic_batch(weights, exported, batch):
    net = NeuralSolver(weights).net
    sets = seeded_batch(batch, SyntheticConfig(), seed=batch).points
    assert onnx_parity(net, exported, [sets]) <= 1e-4


def test_onnx_solver_matches_neural_solver(weights, exported):
    neural, ort_solver = NeuralSolver(weights), OnnxSolver(exported)
    assert ort_solver.name == "onnx" and ort_solver.bounds == neural.bounds
    sets = seeded_batch(600, SyntheticConfig(), seed=3).points.double()
    for a, b in zip(neural(sets), ort_solver(sets), strict=True):
        assert a.dtype == b.dtype == torch.float64 and a.shape == b.shape
        assert float((a - b).abs().max()) <= 1e-4
    pooled = OnnxSolver(exported, threads=2)(sets)  # chunks in two threads give the same numbers
    for a, b in zip(ort_solver(sets), pooled, strict=True):
        assert torch.equal(a, b)
    with pytest.raises(ValueError, match="trained for half-sizes"):
        OnnxSolver(exported, bounds=SizeBounds(2.0, 30.0))


def test_failed_validation_leaves_no_file(tmp_path, monkeypatch):
    torch.manual_seed(1)
    net = SolverNet(TINY)
    monkeypatch.setattr(onnx_export, "PARITY_TOL", -1.0)  # any difference now counts as a mismatch
    out = tmp_path / "bad.onnx"
    with pytest.raises(RuntimeError, match="does not match PyTorch"):
        export_net_onnx(net, out)
    assert not out.exists() and not list(tmp_path.iterdir())

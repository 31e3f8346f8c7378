"""Building the parts of a fit by name: the solver, the sampler and the depth estimator, with their weights.

The parts themselves live below (:mod:`cuboidcli.solvers`, :mod:`cuboidcli.sampling`,
:mod:`cuboidcli.depth`) and take a loaded network or a weights file; the estimator
(:func:`cuboidcli.fitting.pipeline.fit_depth`) takes a built solver and sampler. Turning a setting and a
``--weights`` value into those is done here, with the weights registry (:mod:`cuboidcli.weights`):

- :func:`make_solver`: numerical, neural or ONNX, from a :class:`~cuboidcli.fitting.config.FitConfig`;
- :func:`make_sampler`: uniform, sequential, local or learned; :func:`load_learned_sampler` the latter;
- :func:`make_depth_estimator`: the built-in depth network or a user's ONNX model;
  :func:`depth_estimator` the same for :class:`DepthModelOptions`, built once per process;
  :func:`depth_for_fit` depth from an RGB image in one call.

:class:`cuboidcli.api.Fitter` builds its solver and sampler here; so do the evaluation runs, the scripts
and the benchmarks.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.fitting.config import FitConfig
from cuboidcli.sampling import LocalSampler, Sampler, SequentialSampler, UniformSampler
from cuboidcli.solvers.base import CuboidSolver, SizeBounds
from cuboidcli.weights import resolve, weights_for


def make_solver(
    config: FitConfig,
    weights_dir: str | os.PathLike | None = None,
    onnx_path: str | os.PathLike | None = None,
    device: str = "cpu",
) -> CuboidSolver:
    """The solver ``config.solver`` names, bounded by ``config.a_min`` and ``config.a_max``. ``weights_dir``:
    a ``--weights`` value for the neural solver (None: the shipped weights); ``onnx_path``: the exported
    solver for ``onnx``. Raises ValueError for an unknown name, FileNotFoundError for missing weights."""
    bounds = SizeBounds(config.a_min, config.a_max)
    if config.solver == "numerical":
        from cuboidcli.solvers.numerical import NumericalSolver

        return NumericalSolver(
            bounds=bounds, lr=config.solver_lr, iters=config.solver_iters, backend=config.backend
        )
    if config.solver == "neural":
        from cuboidcli.solvers.neural import NeuralSolver

        weights = resolve("solver", weights_for("solver", weights_dir))
        return NeuralSolver(weights=weights, device=device, bounds=bounds)
    if config.solver == "onnx":
        from cuboidcli.solvers.onnx import OnnxSolver

        if onnx_path is None:
            raise ValueError("the onnx solver needs an ONNX file (--onnx solver.onnx)")
        return OnnxSolver(str(onnx_path), bounds)
    raise ValueError(f"unknown solver {config.solver!r}; choose numerical, neural or onnx")


def make_sampler(name: str, weights_dir: str | os.PathLike | None = None, device: str = "cpu") -> Sampler:
    """The sampler ``name`` names; ``weights_dir``: a ``--weights`` value for the learned one."""
    if name == "uniform":
        return UniformSampler()
    if name == "sequential":
        return SequentialSampler()
    if name == "local":
        return LocalSampler()
    if name == "learned":
        return load_learned_sampler(weights_for("sampler", weights_dir), device)
    raise ValueError(f"unknown sampler {name!r}; choose uniform, sequential, local or learned")


def load_learned_sampler(weights: str | os.PathLike | None = None, device: str = "cpu"):
    """The learned sampler with the weights a ``--weights`` value names (:func:`cuboidcli.weights.resolve`:
    a .pt file as given, ``<folder>/sampler_v2.pt``, None: ``models/sampler_v2.pt`` or
    ``$CUBOIDS_SAMPLER_WEIGHTS``). Raises FileNotFoundError when that file is missing."""
    from cuboidcli.sampling.learned import LearnedSampler

    return LearnedSampler.load(resolve("sampler", weights), device=device)


def make_depth_estimator(
    model: str | os.PathLike | None = None,
    kind: str = "metric",
    scale: float | None = None,
    shift: float | None = None,
    ref_depth: np.ndarray | None = None,
    device: str = "cpu",
):
    """The estimator for a ``--depth-model`` option: None = the built-in network (``models/depth_v3.pt`` or
    ``$CUBOIDS_DEPTH_WEIGHTS``), a ``.pt`` checkpoint of the built-in network, or an ``.onnx`` model with
    its ``kind`` and alignment (:mod:`cuboidcli.depth.estimator`)."""
    from cuboidcli.depth.estimator import BuiltinDepthEstimator, OnnxDepthEstimator

    if model is None or Path(model).suffix.lower() == ".pt":
        if kind != "metric" or scale is not None or shift is not None or ref_depth is not None:
            raise ValueError(
                "the built-in depth network predicts metric depth; kind, scale, shift and a partial depth "
                "map apply to an ONNX model (--depth-model model.onnx)"
            )
        return BuiltinDepthEstimator(resolve("depth", model), device=device)
    if Path(model).suffix.lower() == ".onnx":
        return OnnxDepthEstimator(model, kind=kind, scale=scale, shift=shift, ref_depth=ref_depth)
    raise ValueError(
        f"depth model {model}: expected an .onnx file (or a .pt checkpoint of the built-in network)"
    )


def depth_for_fit(
    rgb: np.ndarray,
    camera: Camera,
    model: str | os.PathLike | None = None,
    kind: str = "metric",
    scale: float | None = None,
    shift: float | None = None,
    partial_depth: np.ndarray | None = None,
    device: str = "cpu",
    timing: dict | None = None,
) -> tuple[np.ndarray, str]:
    """Depth for ``fit_depth`` from an RGB image: ``(depth_m float32 (H, W), one-line description)``.

    rgb: (H, W, 3) uint8 RGB; camera: its intrinsics. ``model`` etc. as :func:`make_depth_estimator`;
    ``partial_depth`` (H, W) metres, 0 = unknown, aligns a relative model's output. ``timing``: a dict
    that receives ``"depth"``, the seconds of the estimation itself (building the estimator excluded).
    """
    from cuboidcli.depth.estimator import estimate_depth

    estimator = make_depth_estimator(model, kind, scale, shift, partial_depth, device)
    return estimate_depth(estimator, rgb, camera, timing)


@dataclass(frozen=True)
class DepthModelOptions:
    """How to get depth from an RGB image when no depth map is given (:mod:`cuboidcli.depth`)."""

    model: str | None = None
    """None = the built-in network (models/depth_v3.pt); a .pt checkpoint or a user's .onnx model."""
    kind: str = "metric"
    """metric | relative | relative-inverse (for ONNX models)."""
    scale: float | None = None
    shift: float | None = None
    partial_depth: str | None = None
    """Sparse/partial depth map (same size as the image) to align a relative model to."""
    device: str = "cpu"


@lru_cache(maxsize=4)
def depth_estimator(opts: DepthModelOptions, depth_scale: float = 0.001):
    """The depth estimator for these options, built once per process: a folder of images, or every frame of
    an evaluation, loads the network (or a user's ONNX session) once; loading is start-up, not fitting time.
    ``depth_scale``: metres per unit of ``opts.partial_depth`` when that is a PNG."""
    from cuboidcli.io.depth import read_depth

    partial = read_depth(opts.partial_depth, depth_scale) if opts.partial_depth else None
    return make_depth_estimator(opts.model, opts.kind, opts.scale, opts.shift, partial, opts.device)

"""Building the parts of a fit by name: the solver, the sampler and the depth estimator, with their weights.

The parts themselves live below (:mod:`cuboidcli.solvers`, :mod:`cuboidcli.sampling`,
:mod:`cuboidcli.depth`) and take a loaded network or a weights file; the estimator
(:func:`cuboidcli.fitting.pipeline.fit_depth`) takes a built solver and sampler. Turning a setting and a
``--weights`` value into those is done here, with the weights registry (:mod:`cuboidcli.weights`):

- :func:`make_solver` and :func:`make_sampler`: the part a name of the registry
  (:data:`cuboidcli.fitting.parts.PARTS`) stands for, built by its builder (a function in the part's own
  module, ``cuboidcli.solvers.numerical:build``) with the weights file of its network;
  :func:`load_learned_sampler` the learned sampler from a weights value;
- :func:`make_depth_estimator`: the built-in depth network, a user's ONNX model or a Hugging Face model;
  :func:`depth_estimator` the same for :class:`DepthModelOptions`, built once per process (depth from an
  RGB image is :func:`cuboidcli.load.frame.depth_from_rgb`, the one place that asks for it).

:class:`cuboidcli.api.Fitter` builds its solver and sampler here; so do the evaluation runs, the scripts
and the benchmarks.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import lru_cache
from pathlib import Path

import numpy as np

from cuboidcli.fitting import parts
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.parts import BuildInputs
from cuboidcli.sampling import Sampler
from cuboidcli.solvers.base import CuboidSolver
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
    return _build(parts.find("solver", config.solver), config, weights_dir, onnx_path, device)


def make_sampler(
    name: str,
    weights_dir: str | os.PathLike | None = None,
    device: str = "cpu",
    config: FitConfig | None = None,
) -> Sampler:
    """The sampler ``name`` names; ``weights_dir``: a ``--weights`` value for the learned one. ``config``:
    the fit's settings, for a sampler that reads them (default: FitConfig's defaults)."""
    return _build(parts.find("sampler", name), config or FitConfig(), weights_dir, None, device)


def _build(part: parts.Part, config: FitConfig, weights_dir, onnx_path, device: str):
    """The part built with the file of its network that a ``--weights`` value names
    (:func:`cuboidcli.weights.weights_for`, then :func:`~cuboidcli.weights.resolve`)."""
    weights = None if part.network is None else resolve(part.network, weights_for(part.network, weights_dir))
    onnx = None if onnx_path is None else Path(onnx_path)
    return part.build(BuildInputs(config, weights, onnx, device))


def load_learned_sampler(weights: str | os.PathLike | None = None, device: str = "cpu"):
    """The learned sampler with the weights a ``--weights`` value names (:func:`cuboidcli.weights.resolve`:
    a .pt file as given, ``<folder>/sampler_v2.pt``, None: ``models/sampler_v2.pt`` or
    ``$CUBOIDS_SAMPLER_WEIGHTS``). Raises FileNotFoundError when that file is missing."""
    from cuboidcli.sampling.learned import LearnedSampler

    return LearnedSampler.load(resolve("sampler", weights), device=device)


def make_depth_estimator(
    model: str | os.PathLike | None = None,
    kind: str | None = None,
    scale: float | None = None,
    shift: float | None = None,
    ref_depth: np.ndarray | None = None,
    device: str = "cpu",
    *,
    camera_height_m: float | None = None,
    onnx_preset: str | None = None,
    onnx_mean: tuple[float, float, float] | None = None,
    onnx_std: tuple[float, float, float] | None = None,
    onnx_size: int | None = None,
    onnx_multiple: int | None = None,
):
    """The estimator for a ``--depth-model`` option:

    - None: the built-in network (``models/depth_v4.pt`` or ``$CUBOIDS_DEPTH_WEIGHTS``); a ``.pt`` file: a
      checkpoint of the built-in network (both metric: ``kind`` None or "metric", no scale);
    - an ``.onnx`` file, with its ``kind`` (None: the preset's, else metric), alignment and the ``onnx_*``
      conventions (:class:`cuboidcli.depth.estimator.OnnxDepthEstimator`, presets in
      :mod:`cuboidcli.depth.onnx_presets`);
    - ``hf:owner/name`` or a folder saved with ``save_pretrained``: a Hugging Face ``transformers``
      depth-estimation model (:class:`cuboidcli.depth.hf.HFDepthEstimator`; ``kind`` None: what its
      config says).

    Relative kinds need one scale source: ``scale`` (and ``shift``), ``ref_depth`` (a partial depth map
    in metres, (H, W), 0 = unknown) or ``camera_height_m`` (the camera's height above the floor).
    Raises a one-line ValueError (FileNotFoundError for a missing file) for anything unusable.
    """
    from cuboidcli.depth.estimator import BuiltinDepthEstimator
    from cuboidcli.depth.hf import HFDepthEstimator, is_hf_model
    from cuboidcli.depth.onnx import OnnxDepthEstimator

    onnx_opts = {
        "preset": onnx_preset, "mean": onnx_mean, "std": onnx_std, "size": onnx_size,
        "size_multiple": onnx_multiple,
    }  # fmt: skip
    is_onnx = model is not None and not is_hf_model(model) and Path(model).suffix.lower() == ".onnx"
    if not is_onnx and any(v is not None for v in onnx_opts.values()):
        raise ValueError("the ONNX preset, mean, std, size and multiple apply to an .onnx depth model only")
    if model is None or (not is_hf_model(model) and Path(model).suffix.lower() == ".pt"):
        extra = (scale, shift, ref_depth, camera_height_m)
        if kind not in (None, "metric") or any(v is not None for v in extra):
            raise ValueError(
                "the built-in depth network predicts metric depth; kind, scale, shift, a partial depth map "
                "and the camera height apply to an ONNX or Hugging Face model (--depth-model)"
            )
        return BuiltinDepthEstimator(resolve("depth", model), device=device)
    if is_hf_model(model):
        return HFDepthEstimator(model, kind, scale, shift, ref_depth, camera_height_m, device=device)
    if is_onnx:
        mean = onnx_opts.pop("mean")
        std = onnx_opts.pop("std")
        return OnnxDepthEstimator(
            model, kind=kind, scale=scale, shift=shift, ref_depth=ref_depth, mean=mean, std=std,
            camera_height_m=camera_height_m, **onnx_opts,
        )  # fmt: skip
    raise ValueError(
        f"depth model {model}: expected an .onnx file, a Hugging Face model (hf:owner/name or a folder "
        "saved with save_pretrained) or a .pt checkpoint of the built-in network"
    )


@dataclass(frozen=True)
class DepthModelOptions:
    """How to get depth from an RGB image when no depth map is given (:mod:`cuboidcli.depth`). Frozen and
    hashable: :func:`depth_estimator` builds one estimator per distinct options."""

    model: str | None = None
    """None = the built-in network (models/depth_v4.pt); a .pt checkpoint, a user's .onnx model, a
    Hugging Face model id ``hf:owner/name`` or a folder saved with ``save_pretrained``."""
    kind: str | None = None
    """None = what the model predicts (built-in: metric; ONNX: the preset's, else metric; Hugging Face: its
    config's); metric | relative | relative-inverse to override."""
    scale: float | None = None
    shift: float | None = None
    partial_depth: str | None = None
    """Sparse/partial depth map (same size as the image) to align a relative model to."""
    device: str = "cpu"
    camera_height_m: float | None = None
    """The camera's height above the floor in metres: scales a relative model's output (shift 0) so that
    the floor lies this far below the camera."""
    onnx_preset: str | None = None
    """A named ONNX convention (:data:`cuboidcli.depth.onnx_presets.PRESETS`)."""
    onnx_mean: tuple[float, float, float] | None = None
    onnx_std: tuple[float, float, float] | None = None
    """Input normalisation of an ONNX model (overrides the preset's; default ImageNet)."""
    onnx_size: int | None = None
    """Input size of an ONNX model with dynamic axes (the preset's side; overrides the preset's)."""
    onnx_multiple: int | None = None
    """Both input sides of an ONNX model with dynamic axes are rounded to multiples of this."""
    drop_edges: bool = False
    """Leave out the pixels on depth discontinuities of the estimate (:mod:`cuboidcli.depth.edges`): a
    network smears depth across object boundaries, and those points float between the surfaces.

    Off by default: with the built-in network it did not raise AUC@20 on the real or the synthetic frames
    (README, "From a photo"); models with sharper boundaries and stronger smearing may differ."""


@lru_cache(maxsize=4)
def depth_estimator(opts: DepthModelOptions, depth_scale: float = 0.001):
    """The depth estimator for these options, built once per process: a folder of images, or every frame of
    an evaluation, loads the network (or a user's ONNX session) once; loading is start-up, not fitting time.
    ``depth_scale``: metres per unit of ``opts.partial_depth`` when that is a PNG."""
    from cuboidcli.io.depth import read_depth

    partial = read_depth(opts.partial_depth, depth_scale) if opts.partial_depth else None
    return make_depth_estimator(
        opts.model, opts.kind, opts.scale, opts.shift, partial, opts.device,
        camera_height_m=opts.camera_height_m, onnx_preset=opts.onnx_preset,
        onnx_mean=None if opts.onnx_mean is None else tuple(opts.onnx_mean),
        onnx_std=None if opts.onnx_std is None else tuple(opts.onnx_std),
        onnx_size=opts.onnx_size, onnx_multiple=opts.onnx_multiple,
    )  # fmt: skip

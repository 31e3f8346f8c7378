"""Depth from RGB: depth estimators f_v behind one interface and depth errors (:mod:`.evaluate`). The
network itself is :mod:`cuboidcli.nets.depth`, its training :mod:`cuboidcli.learn.depth_train`
(``cuboids train depth``).

Public entry points: :func:`estimate_depth` (what ``cuboids fit image.png`` without ``--depth`` calls, with
an estimator built once), :class:`BuiltinDepthEstimator` (:mod:`.estimator`), :class:`OnnxDepthEstimator`
(:mod:`.onnx`; named conventions in :mod:`.onnx_presets`), :class:`HFDepthEstimator` (Hugging Face
``transformers`` models, ``cuboids[hf]``), :class:`DepthScaling` (relative depth to metres, :mod:`.scale`).
Building an estimator for a ``--depth-model`` value, the shipped weights included, is
:func:`cuboidcli.factories.make_depth_estimator`.
"""

from __future__ import annotations

#: Public name -> module that defines it, imported on first use: the names of the ONNX conventions
#: (:mod:`.onnx_presets`), which the option checks read, must not pull in torch.
_EXPORTS = {
    "BuiltinDepthEstimator": "cuboidcli.depth.estimator",
    "DepthEstimator": "cuboidcli.depth.estimator",
    "estimate_depth": "cuboidcli.depth.estimator",
    "HFDepthEstimator": "cuboidcli.depth.hf",
    "OnnxDepthEstimator": "cuboidcli.depth.onnx",
    "DepthScaling": "cuboidcli.depth.scale",
}

__all__ = sorted(_EXPORTS)


def __getattr__(name: str):
    module = _EXPORTS.get(name)
    if module is None:
        raise AttributeError(f"module 'cuboidcli.depth' has no attribute {name!r}")
    import importlib

    value = getattr(importlib.import_module(module), name)
    globals()[name] = value
    return value

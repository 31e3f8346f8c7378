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

from cuboidcli.depth.estimator import BuiltinDepthEstimator, DepthEstimator, estimate_depth
from cuboidcli.depth.hf import HFDepthEstimator
from cuboidcli.depth.onnx import OnnxDepthEstimator
from cuboidcli.depth.scale import DepthScaling

__all__ = [
    "BuiltinDepthEstimator",
    "DepthEstimator",
    "DepthScaling",
    "HFDepthEstimator",
    "OnnxDepthEstimator",
    "estimate_depth",
]

"""Depth from RGB: depth estimators f_v behind one interface and depth errors (:mod:`.evaluate`). The
network itself is :mod:`cuboidcli.nets.depth`, its training :mod:`cuboidcli.learn.depth_train`
(``cuboids train depth``).

Public entry points: :func:`estimate_depth` (what ``cuboids fit image.png`` without ``--depth`` calls, with
an estimator built once), :class:`BuiltinDepthEstimator`, :class:`OnnxDepthEstimator`. Building an
estimator for a ``--depth-model`` value, the shipped weights included, is
:func:`cuboidcli.factories.make_depth_estimator`.
"""

from cuboidcli.depth.estimator import (
    BuiltinDepthEstimator,
    DepthEstimator,
    OnnxDepthEstimator,
    estimate_depth,
)

__all__ = [
    "BuiltinDepthEstimator",
    "DepthEstimator",
    "OnnxDepthEstimator",
    "estimate_depth",
]

"""Depth from RGB: depth estimators f_v behind one interface and depth errors (:mod:`.evaluate`). The
network itself is :mod:`cuboidcli.nets.depth`, its training :mod:`cuboidcli.learn.depth_train`
(``python -m cuboidcli.depth.train`` still starts it: :mod:`.train` is that entry point alone).

Public entry points: :func:`depth_for_fit` (what ``cuboids fit image.png`` without ``--depth`` calls),
:func:`estimate_depth` (the same with an estimator built once), :func:`make_depth_estimator`,
:class:`BuiltinDepthEstimator`, :class:`OnnxDepthEstimator`.
"""

from cuboidcli.depth.estimator import (
    BuiltinDepthEstimator,
    DepthEstimator,
    OnnxDepthEstimator,
    depth_for_fit,
    estimate_depth,
    make_depth_estimator,
)

__all__ = [
    "BuiltinDepthEstimator",
    "DepthEstimator",
    "OnnxDepthEstimator",
    "depth_for_fit",
    "estimate_depth",
    "make_depth_estimator",
]

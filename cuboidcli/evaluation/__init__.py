"""Evaluation of cuboid abstractions with the paper's metrics (Sec. 4 "Metrics"), datasets and baselines.

Modules: :mod:`.oa` (fused OA-L2 distance), :mod:`.coverage` (image coverage), :mod:`.metrics` (per-frame
metrics, pooled AUC, aggregation), :mod:`.iou` (oriented-box IoU and matching), :mod:`.nyu` (the NYU Depth
v2 ``.mat`` files), :mod:`.presets` (baselines as configurations), :mod:`.runner` (frames, runs, workers),
:mod:`.outputs` (metrics.json, frames.csv, cuboids.csv), :mod:`.raycast` (depth rendering of cuboids,
for tests), :mod:`.shape` (axis angles to gravity and the room's axes, support of the visible faces,
gravity error).
"""

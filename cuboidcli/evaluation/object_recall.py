"""Object recall and precision where a per-pixel instance image exists (synthetic data).

Every valid full-resolution point is assigned to a cuboid with the estimator's own rule
(:func:`cuboidcli.fitting.assign.assign_points`). A ground-truth object (nonzero instance id: walls, floor,
ceiling and clutter too) with at least :data:`OBJECT_MIN_PCT` % of the frame's valid points is *eligible*;
it is *explained* by a cuboid that holds >= :data:`OBJECT_EXPLAIN_PCT` % of the object's valid points while
>= :data:`OBJECT_EXPLAIN_PCT` % of the cuboid's assigned points lie on the object. Recall = explained /
eligible objects; precision = cuboids that explain an eligible object / predicted cuboids; both pooled over
frames by adding up the counts (:class:`ObjectCounts`).
"""

from __future__ import annotations

import math
from typing import NamedTuple

import numpy as np

#: An object is eligible for object recall with at least this percentage of the frame's valid points.
OBJECT_MIN_PCT = 1
#: A cuboid explains an object when it holds at least this percentage of the object's points and at least
#: this percentage of the cuboid's assigned points lie on the object.
OBJECT_EXPLAIN_PCT = 50


class ObjectCounts(NamedTuple):
    """Object recall / precision counts of one frame (pooled by summing)."""

    explained: int
    """Eligible objects explained by a cuboid."""
    eligible: int
    """Objects with >= OBJECT_MIN_PCT % of the frame's valid points."""
    explaining: int
    """Predicted cuboids that explain an eligible object."""
    predicted: int
    """Predicted cuboids."""


def object_counts(labels: np.ndarray, instance_ids: np.ndarray, n_cuboids: int) -> ObjectCounts:
    """Object recall / precision counts from a per-point assignment.

    ``labels`` (N,) per valid point: the cuboid index (>= 0), -1 (none) or -2 (occluded), as
    :func:`cuboidcli.fitting.assign.assign_points` returns; ``instance_ids`` (N,) the ground-truth object id
    of each point (0 = no object). N (all valid points) is the base of the eligibility threshold.
    """
    labels = np.asarray(labels).ravel()
    ids = np.asarray(instance_ids).ravel().astype(np.int64)
    n = ids.size
    if labels.size != n:
        raise ValueError(f"{labels.size} labels for {n} instance ids")
    if n == 0:
        return ObjectCounts(0, 0, 0, n_cuboids)
    present = np.flatnonzero(np.bincount(ids))  # object ids with points, ascending (0 first if present)
    index = np.zeros(int(ids.max()) + 1, dtype=np.int64)
    index[present] = np.arange(present.size)
    obj = index[ids]  # (N,) dense object index
    sizes = np.bincount(obj, minlength=present.size)
    eligible = (present != 0) & (100 * sizes >= OBJECT_MIN_PCT * n)
    n_eligible = int(eligible.sum())
    if n_cuboids == 0 or n_eligible == 0:
        return ObjectCounts(0, n_eligible, 0, n_cuboids)
    on = labels >= 0
    joint = np.bincount(
        obj[on] * n_cuboids + labels[on].astype(np.int64), minlength=present.size * n_cuboids
    ).reshape(present.size, n_cuboids)  # joint[o, h]: points of object o assigned to cuboid h
    assigned = joint.sum(axis=0)  # points assigned to each cuboid (on any object or none)
    explains = (
        eligible[:, None]
        & (joint > 0)
        & (100 * joint >= OBJECT_EXPLAIN_PCT * sizes[:, None])
        & (100 * joint >= OBJECT_EXPLAIN_PCT * assigned[None, :])
    )
    return ObjectCounts(
        explained=int(explains.any(axis=1).sum()),
        eligible=n_eligible,
        explaining=int(explains.any(axis=0).sum()),
        predicted=n_cuboids,
    )


def object_rates(explained: int, eligible: int, explaining: int, predicted: int) -> dict:
    """Object recall and precision in % (NaN with a zero denominator)."""
    return {
        "object_recall_pct": 100.0 * explained / eligible if eligible else math.nan,
        "object_precision_pct": 100.0 * explaining / predicted if predicted else math.nan,
    }

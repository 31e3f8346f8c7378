"""A room's coordinates in metres, and whether they can be a room: a scan file's coordinates, read as
stored (:func:`cuboidcli.io.scan.read_scan`), are scaled by its ``--unit`` (:func:`in_metres`), and every
room, a file, a fused sequence or points in memory, passes the same plausibility checks
(:func:`check_cloud`), whose refusals name the unit the coordinates probably are in."""

from __future__ import annotations

import math

import numpy as np

from cuboidcli.io.depth import InputError
from cuboidcli.io.scan import MIN_POINTS, UNITS, PointCloud

__all__ = ["MAX_DIAGONAL_M", "MIN_DIAGONAL_M", "UNITS", "check_cloud", "check_unit", "in_metres"]

#: Plausible bounding-box diagonals of a scene, metres (a corner of a desk up to a large building floor).
#: The lower bound catches a scan in metres read with ``--unit cm``: a room of up to 30 m across then reads
#: as at most 30 cm (at 5 cm, ScanNet's 6.75 m scene0003_00 with ``--unit cm`` fitted 0 cuboids to 3 points,
#: exit 0, no warning).
MIN_DIAGONAL_M = 0.3
MAX_DIAGONAL_M = 200.0
_UNIT_NAMES = {"m": "metres", "cm": "centimetres", "mm": "millimetres"}


def check_unit(unit: str) -> float:
    """Metres per unit of ``unit``; InputError naming the choices when it is unknown."""
    if unit not in UNITS:
        raise InputError(f"unknown unit {unit!r}; choose one of: {', '.join(UNITS)}")
    return UNITS[unit]


def in_metres(cloud: PointCloud, unit: str) -> PointCloud:
    """A scan file's cloud as :func:`~cuboidcli.io.scan.read_scan` read it, in ``unit``, made metres and
    checked (:func:`check_cloud`), in place: its points scaled, its meta's ``unit`` recorded and a mesh's
    surface area given in square metres (``surface_area_m2``)."""
    scale = check_unit(unit)
    cloud.points = np.asarray(cloud.points, dtype=np.float64) * scale
    read = cloud.meta
    meta = {"path": read["path"], "format": read["format"], "unit": unit}
    for key, value in read.items():
        if key == "surface_area":
            meta["surface_area_m2"] = value * scale * scale
        else:
            meta.setdefault(key, value)
    cloud.meta = meta
    return check_cloud(cloud, unit)


def _unit_hint(diagonal_m: float, unit: str) -> str | None:
    """The unit that would make a bounding box of ``diagonal_m`` (read with ``unit``) room-sized."""
    best = None
    for name, metres in UNITS.items():
        d = diagonal_m * metres / UNITS[unit]
        if name != unit and MIN_DIAGONAL_M <= d <= MAX_DIAGONAL_M:
            score = abs(math.log(d / 5.0))  # a room is a few metres across
            if best is None or score < best[0]:
                best = (score, name)
    return None if best is None else best[1]


def check_cloud(cloud: PointCloud, unit: str) -> PointCloud:
    """Plausibility checks shared by files and fused sequences; raises InputError, adds warnings.

    Refuses NaN/inf coordinates, fewer than :data:`~cuboidcli.io.scan.MIN_POINTS` points and a bounding
    box diagonal outside [:data:`MIN_DIAGONAL_M`, :data:`MAX_DIAGONAL_M`] metres (naming the ``--unit``
    that would fit). Normals that are not unit vectors are dropped with a warning.
    """
    check_unit(unit)
    name = cloud.meta.get("path", "the point cloud")
    points = cloud.points
    if points.ndim != 2 or points.shape[1] != 3:
        raise InputError(f"{name}: points have shape {points.shape}; expected (N, 3)")
    bad = int((~np.isfinite(points).all(axis=1)).sum())
    if bad:
        raise InputError(
            f"{name}: {bad} of {len(points)} points have NaN or inf coordinates; remove them and retry"
        )
    if len(points) < MIN_POINTS:
        raise InputError(f"{name} has {len(points)} points; a room needs at least {MIN_POINTS}")
    diagonal = float(np.linalg.norm(points.max(axis=0) - points.min(axis=0)))
    if not MIN_DIAGONAL_M <= diagonal <= MAX_DIAGONAL_M:
        size = f"{diagonal:.0f} m" if diagonal > 1.0 else f"{diagonal * 1000:.1f} mm"
        verdict, hint = "too large" if diagonal > 1.0 else "too small", _unit_hint(diagonal, unit)
        if "layout" in cloud.meta:  # fused from depth maps: the depth scale and the poses set its size
            read, fix = "", "check --depth-scale and that the poses are in metres"
        else:
            read = f" with --unit {unit}"
            fix = f"check --unit (coordinates read as {_UNIT_NAMES[unit]})"
            fix = fix if hint is None else f"it looks like {_UNIT_NAMES[hint]}: pass --unit {hint}"
        raise InputError(f"{name} is {size} across{read}: {verdict} for a room; {fix}")
    if cloud.normals is not None:
        norm = np.linalg.norm(cloud.normals, axis=1)
        off = int((~(np.abs(norm - 1.0) < 1e-3)).sum())
        if off:
            cloud.warnings.append(f"{off} of {len(points)} normals are zero or not finite; normals dropped")
            cloud.normals = None
    cloud.meta["points"] = len(points)
    cloud.meta["diagonal_m"] = round(diagonal, 4)
    return cloud

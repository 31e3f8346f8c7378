"""The metric scale of a relative depth map from the camera's height above the floor.

A relative monocular network gives depth up to an unknown factor. When the user knows how high the camera
was held (a phone at chest height, a robot's camera mount), the factor follows from the floor: back-project
the relative depth with the camera, estimate gravity from the scene's Manhattan frame
(:func:`cuboidcli.geometry.gravity.estimate_gravity`), take the floor as the lowest large horizontal plane
below the camera, and scale the map so that the camera lies ``camera_height_m`` above that plane.

The relative depth must be depth up to scale only (shift 0): an affine-invariant output with a real shift
bends the back-projected planes and biases the scale. :func:`scale_from_camera_height` is what
:class:`cuboidcli.depth.estimator.DepthScaling` calls for ``camera_height_m``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.geometry.gravity import estimate_gravity, grid_normals

#: The relative map is first brought to this median depth (metres, a room's typical distance) so that the
#: metric thresholds of the normal estimation (:func:`grid_normals`) and of the plane bands apply.
TYPICAL_DEPTH_M = 2.5
#: Grid cells of a horizontal surface: normal within this angle of gravity.
HORIZONTAL_DEG = 10.0
#: Width of the height slices (in the normalised map's metres) that group horizontal cells into planes.
BAND = 0.03
#: A plane is "large" when it holds at least this share of the map's valid grid cells (and 30 cells).
MIN_FLOOR_SHARE = 0.03


@dataclass(frozen=True)
class FloorScale:
    """The result of :func:`scale_from_camera_height`."""

    scale: float
    """Metres per unit of the relative depth: metric depth = scale * relative depth."""
    floor_distance: float
    """The floor's distance below the camera in units of the relative depth."""
    down: tuple[float, float, float]
    """Gravity in camera coordinates (unit vector)."""
    floor_cells: int
    """Grid cells on the floor plane."""


def _grid_step(height: int, width: int, cells: int = 160) -> int:
    """The pixel step that gives about ``cells`` grid cells along the longer side."""
    return max(1, round(max(height, width) / cells))


def scale_from_camera_height(depth_rel: np.ndarray, camera: Camera, camera_height_m: float) -> FloorScale:
    """The factor that turns ``depth_rel`` (H, W), depth up to scale (0/NaN = unknown), into metres, given
    that the camera was ``camera_height_m`` above the floor.

    Raises a one-line ValueError for a non-positive height, a map without enough valid depth, a scene
    whose gravity cannot be estimated, or one without a large horizontal plane below the camera.
    """
    if not (
        isinstance(camera_height_m, (int, float)) and math.isfinite(camera_height_m) and camera_height_m > 0
    ):
        raise ValueError(f"the camera height must be a positive number of metres, got {camera_height_m}")
    d = np.asarray(depth_rel, dtype=np.float64)
    valid = np.isfinite(d) & (d > 0)
    if valid.sum() < 100:
        raise ValueError(
            "no floor found for the camera height: the relative depth has almost no valid pixels"
        )
    norm = TYPICAL_DEPTH_M / float(np.median(d[valid]))
    d = np.where(valid, d * norm, 0.0)
    step = _grid_step(*d.shape)
    grid = camera.backproject(d, step)
    gravity = estimate_gravity(grid)
    if gravity is None:
        raise ValueError(
            "no floor found for the camera height: gravity could not be estimated from the relative depth "
            "(no floor or walls in view?); give a scale or a partial depth map instead"
        )
    down = gravity.down
    normals, idx = grid_normals(grid)
    points = grid.reshape(-1, 3)[idx]
    horizontal = np.abs(normals @ down) > math.cos(math.radians(HORIZONTAL_DEG))
    h = points[horizontal] @ down  # distance below the camera along gravity
    h = h[h > 0]
    min_cells = max(30, int(MIN_FLOOR_SHARE * valid[::step, ::step].sum()))
    if len(h) < min_cells:
        raise ValueError(
            "no floor found for the camera height: no large horizontal surface below the camera in view"
        )
    bins = np.floor(h / BAND).astype(np.int64)
    counts = np.bincount(bins)
    smooth = counts + np.concatenate([[0], counts[:-1]]) + np.concatenate([counts[1:], [0]])
    large = np.flatnonzero(smooth >= min_cells)
    if len(large) == 0:
        raise ValueError(
            "no floor found for the camera height: no large horizontal surface below the camera in view"
        )
    lowest = int(large.max())  # the farthest below the camera: the floor, not a table top
    lo = max(lowest - 1, 0)
    centre = lo + int(np.argmax(counts[lo : lowest + 2]))
    near = np.abs(h - (centre + 0.5) * BAND) <= 1.5 * BAND
    floor = float(np.median(h[near]))
    distance = floor / norm
    return FloorScale(
        scale=float(camera_height_m / distance),
        floor_distance=distance,
        down=tuple(float(x) for x in down),
        floor_cells=int(near.sum()),
    )

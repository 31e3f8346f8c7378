"""A depth model's raw output in metres: :class:`DepthScaling`, and the scale of relative depth from the
camera's height above the floor.

A metric model's output is metres already. A relative one gives depth (or inverse depth) up to an unknown
scale and shift; :class:`DepthScaling` takes exactly one source for them: a given scale (and shift), a
least-squares fit to a partial reference depth map (:func:`fit_scale_shift`), or the camera's height.

When the user knows how high the camera was held (a phone at chest height, a robot's camera mount), the
factor follows from the floor (:func:`scale_from_camera_height`): back-project the relative depth with the
camera, estimate gravity from the scene's Manhattan frame
(:func:`cuboidcli.geometry.gravity.estimate_gravity`), take the floor as the lowest large horizontal plane
below the camera, and scale the map so that the camera lies ``camera_height_m`` above that plane. The
relative depth must be depth up to scale only (shift 0): an affine-invariant output with a real shift
bends the back-projected planes and biases the scale.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.geometry.gravity import estimate_gravity, grid_normals

#: What a depth model's output holds (:class:`DepthScaling`).
KINDS = ("metric", "relative", "relative-inverse")


class DepthScaling:
    """How a model's raw output becomes metres: ``kind`` (metric | relative | relative-inverse) and, for
    relative kinds, exactly one source of scale: ``scale`` (and ``shift``, default 0), ``ref_depth`` (a
    partial depth map (H, W) in metres, 0/NaN where unknown, to which scale and shift are fitted by least
    squares) or ``camera_height_m`` (the camera's height above the floor: the output is taken with shift 0
    and scaled so that the floor lies that far below the camera, :mod:`cuboidcli.depth.scale`).

    Built before any network is loaded, so that a wrong combination fails at once (one-line ValueError).
    """

    def __init__(
        self,
        kind: str = "metric",
        scale: float | None = None,
        shift: float | None = None,
        ref_depth: np.ndarray | None = None,
        camera_height_m: float | None = None,
    ) -> None:
        check_alignment_args(kind, scale, shift, ref_depth, camera_height_m)
        self.kind, self.scale, self.shift, self.ref_depth = kind, scale, shift, ref_depth
        self.camera_height_m = camera_height_m
        self.alignment: tuple[float, float, int] | None = None
        """(scale, shift, pixels) of the last least-squares fit to ``ref_depth``."""
        self.floor = None
        """The last :class:`cuboidcli.depth.scale.FloorScale` for ``camera_height_m``."""

    def to_metres(self, raw: np.ndarray, camera: Camera) -> np.ndarray:
        """Metric depth float32 (H, W) from the raw output (H, W); non-positive or non-finite -> 0."""
        raw = np.asarray(raw, dtype=np.float64)
        inverse = self.kind == "relative-inverse"
        if self.kind == "metric":
            depth = raw
        elif self.camera_height_m is not None:
            with np.errstate(divide="ignore", invalid="ignore"):
                unscaled = 1.0 / raw if inverse else raw  # shift 0: depth up to scale
            unscaled = np.where(np.isfinite(unscaled) & (unscaled > 0), unscaled, 0.0)
            self.floor = scale_from_camera_height(unscaled, camera, self.camera_height_m)
            depth = self.floor.scale * unscaled
        else:
            if self.ref_depth is not None:
                scale, shift, n = fit_scale_shift(raw, self.ref_depth, inverse)
                self.alignment = (scale, shift, n)
            else:
                scale, shift = self.scale, self.shift or 0.0
            aligned = scale * raw + shift
            with np.errstate(divide="ignore", invalid="ignore"):
                depth = 1.0 / aligned if inverse else aligned
        depth = np.where(np.isfinite(depth) & (depth > 0), depth, 0.0)
        return depth.astype(np.float32)

    def describe(self) -> str:
        """The kind and how it was scaled, e.g. "relative-inverse, scale 2, shift 0"."""
        if self.kind == "metric":
            return "metric"
        if self.camera_height_m is not None:
            text = f"{self.kind}, scaled to a camera {self.camera_height_m:g} m above the floor"
            if self.floor is not None:
                text += (
                    f" (floor at {self.floor.floor_distance:.4g} model units: scale {self.floor.scale:.4g})"
                )
            return text
        if self.ref_depth is not None:
            if self.alignment is None:
                return f"{self.kind}, aligned to the partial depth map"
            s, b, n = self.alignment
            return (
                f"{self.kind}, aligned to the partial depth map over {n} pixels: scale {s:.4g}, shift {b:.4g}"
            )
        return f"{self.kind}, scale {self.scale:g}, shift {self.shift or 0.0:g}"


def check_alignment_args(kind: str, scale, shift, ref_depth, camera_height_m=None) -> None:
    """One-line ValueError unless ``kind`` and its scale sources fit together (:class:`DepthScaling`)."""
    if kind not in KINDS:
        raise ValueError(f"unknown depth model kind {kind!r}; choose one of {', '.join(KINDS)}")
    given = scale is not None or shift is not None
    height = camera_height_m is not None
    if kind == "metric":
        if given or ref_depth is not None or height:
            raise ValueError(
                "a metric depth model needs no scale, shift, partial depth or camera height; "
                "use kind 'relative'"
            )
        return
    if given + (ref_depth is not None) + height > 1:
        raise ValueError(
            "give one of a scale (and shift), a partial depth map to fit them to, or the camera height, "
            "not both"
        )
    if not given and ref_depth is None and not height:
        raise ValueError(
            f"a {kind} depth model gives depth only up to scale: it needs a scale (--relative-scale), a "
            "partial depth map to align its output to (--partial-depth), or the camera's height above the "
            "floor (--camera-height)"
        )
    if shift is not None and scale is None:
        raise ValueError("a shift needs a scale as well (pass scale 1 for a shift alone)")
    if scale is not None and not (math.isfinite(scale) and scale > 0):
        raise ValueError(f"the depth scale must be a positive number, got {scale}")
    if height and not (math.isfinite(camera_height_m) and camera_height_m > 0):
        raise ValueError(f"the camera height must be a positive number of metres, got {camera_height_m}")


def fit_scale_shift(
    raw: np.ndarray, ref_depth: np.ndarray, inverse: bool = False
) -> tuple[float, float, int]:
    """Least-squares (scale, shift) with scale * raw + shift ~ ref_depth (or ~ 1 / ref_depth if
    ``inverse``) over the pixels where the reference is finite and positive and ``raw`` is finite.

    raw, ref_depth: (H, W). Returns (scale, shift, number of pixels used). Raises ValueError for a
    reference of the wrong size, too few pixels, a constant model output or a non-positive scale.
    """
    ref = np.asarray(ref_depth, dtype=np.float64)
    if ref.shape != raw.shape:
        raise ValueError(
            f"the partial depth map has shape {ref.shape} but the image is {raw.shape[1]}x{raw.shape[0]} "
            f"(expected {raw.shape}); the depth map must be registered to the image"
        )
    mask = np.isfinite(ref) & (ref > 0) & np.isfinite(raw)
    n = int(mask.sum())
    if n < 2:
        raise ValueError(
            f"the partial depth map has {n} valid pixels; at least 2 are needed to fit scale and shift"
        )
    target = 1.0 / ref[mask] if inverse else ref[mask]
    x = raw[mask]
    a = np.stack([x, np.ones_like(x)], 1)
    if np.ptp(x) <= 1e-12 * max(1.0, float(np.abs(x).max())):
        raise ValueError(
            "the depth model's output is constant on the partial depth's pixels; cannot fit a scale"
        )
    (scale, shift), *_ = np.linalg.lstsq(a, target, rcond=None)
    if scale <= 0:
        hint = "relative" if inverse else "relative-inverse"
        raise ValueError(
            f"aligning the model's output to the partial depth gave a negative scale ({scale:.3g}); "
            f"does the model predict the other kind? try '{hint}'"
        )
    return float(scale), float(shift), n


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

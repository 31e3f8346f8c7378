"""A frame as the estimator's input (:func:`frame_input`): the fitting grid of a depth map
(:func:`prepare_points`), the orientation constraint from gravity (:func:`resolve_alignment`: the depth
map's surfaces and, where the frame has a photo, its lines), and the per-cell labels of the selected
cuboids (:func:`grid_assignment`)."""

from __future__ import annotations

import time
from typing import TYPE_CHECKING

import numpy as np

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.fitting.align import Alignment
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.fit_input import FitInput, ImageGrid
from cuboidcli.geometry.arrays import as_kind, numpy64
from cuboidcli.geometry.cells import ImageCells
from cuboidcli.geometry.down import combine_down
from cuboidcli.geometry.gravity import Gravity, estimate_gravity, given_gravity, manhattan_axes

if TYPE_CHECKING:
    from cuboidcli.geometry.vanishing import LineEstimate

#: Label of a fitting-grid cell without depth (:func:`grid_assignment`).
INVALID = -3


def prepare_points(depth_m: np.ndarray, camera: Camera, grid_step: int, device: str = "cpu") -> FitInput:
    """A frame's fitting points on its grid: every grid_step-th pixel (nearest, no averaging), invalid depth
    excluded; seen from the camera, not yet aligned (:func:`frame_input` adds gravity). Numpy arrays on
    the CPU, tensors on another ``device``."""
    if depth_m.shape != (camera.height, camera.width):
        raise ValueError(
            f"depth map is {depth_m.shape[1]}x{depth_m.shape[0]} but the camera is "
            f"{camera.width}x{camera.height}"
        )
    # Subsample before masking: on a 12 MP photo the full-size mask would cost more than the fit's grid.
    sub = depth_m[::grid_step, ::grid_step]
    grid = camera.backproject_grid(np.where(valid_depth(sub), sub, 0.0), grid_step)
    depth_grid = grid[..., 2]
    flat = grid.reshape(-1, 3)
    ok = np.flatnonzero(flat[:, 2] > 0)
    u, v = camera.pixel_grid(grid_step)
    cells = ImageCells.of_grid(ok, (u[0] - camera.cx) / camera.fx, (v[:, 0] - camera.cy) / camera.fy)
    image_grid = ImageGrid(
        index=ok,
        shape=depth_grid.shape,
        depth=depth_grid.astype(np.float32),
        step=grid_step,
        focal_cells=(camera.fx / grid_step, camera.fy / grid_step),
        cells=cells,
    )
    inp = FitInput("frame", flat[ok].astype(np.float32), "camera", grid=image_grid)
    if str(device).split(":")[0] == "cpu":
        return inp
    inp = inp.as_tensors()
    inp.points, inp.grid.depth = inp.points.to(device), inp.grid.depth.to(device)
    return inp


def frame_input(
    depth_m: np.ndarray,
    camera: Camera,
    config: FitConfig,
    lines: LineEstimate | None = None,
    depth_predicted: bool = False,
) -> FitInput:
    """A depth map (H, W) metres seen by ``camera`` as the estimator's input: the fitting grid of
    ``config.step_for`` its size, gravity and the orientation constraint (:func:`resolve_alignment`).

    ``lines``: what the frame's photo's lines say (in ``camera``'s frame), a prior on the down direction
    and the room's axes; ``depth_predicted``: the depth map was predicted from that photo (the lines come
    first), else measured (the lines only cross-check it)."""
    t0 = time.perf_counter()
    inp = prepare_points(depth_m, camera, config.step_for(*depth_m.shape), config.device)
    inp.started = t0
    inp.timing_s["prepare"] = time.perf_counter() - t0
    t = time.perf_counter()
    gravity, alignment, warning = resolve_alignment(inp, config, lines, depth_predicted)
    if config.align != "free" or config.gravity_down is not None:
        inp.timing_s["gravity"] = time.perf_counter() - t
    inp.gravity, inp.alignment = gravity, alignment
    # without gravity the camera's y axis stands for down when telling a floor from a wall
    inp.down = np.asarray(gravity.down if gravity is not None else (0.0, 1.0, 0.0), dtype=np.float64)
    if warning:
        inp.warnings.append(warning)
    return inp


def resolve_alignment(
    prep: FitInput, config: FitConfig, lines: LineEstimate | None = None, depth_predicted: bool = False
) -> tuple[Gravity | None, Alignment | None, str]:
    """Gravity and the orientation constraint of a fit: (gravity or None, alignment or None, warning).

    A given ``config.gravity_down`` is used as it is; otherwise, when ``config.align`` needs it, the down
    direction comes from the depth map (geometry/gravity.py) and the photo's ``lines``, by the rule of
    :func:`cuboidcli.geometry.down.combine_down` (a photo, ``depth_predicted``: the lines first; a depth
    map: its own estimate, kept unless unsure). "manhattan" also needs the room's horizontal axes: those
    of the estimate used (with a given down, of the one that would be used), made exactly perpendicular
    to the down direction. Without any estimate the fit stays free, with a warning; with an unsure one,
    a warning says so (where there was a photo to ask).
    """
    if config.align == "free" and config.gravity_down is None:
        return None, None, ""
    hs, ws = prep.grid.shape
    grid = np.zeros((hs * ws, 3))
    grid[as_kind(prep.grid.index, grid)] = numpy64(prep.points)
    grid = grid.reshape(hs, ws, 3)
    estimated = estimate_gravity(grid, seed=config.seed)
    choice = combine_down(estimated, lines, lines_first=depth_predicted)
    warning = choice.note if (depth_predicted or lines is not None) else ""
    if config.gravity_down is not None:
        gravity, warning = given_gravity(config.gravity_down), ""
        found = choice.gravity
        if found is not None and found.frame is not None:  # its room axes, made vertical for the given down
            axes = manhattan_axes(gravity.down, found.frame)
            gravity = Gravity(gravity.down, "given", 1.0, axes, found.support)
    else:
        gravity = choice.gravity
    if config.align == "free":
        return gravity, None, ""
    if gravity is None:
        where = "this depth map" if not depth_predicted and lines is None else "this photo"
        return (
            None,
            None,
            (
                f"no reliable gravity in {where} (too few floor, wall or table surfaces"
                f"{'' if where == 'this depth map' else ', no vanishing points in its lines'}); "
                f"cuboids are fitted free instead of {config.align}-aligned (give --gravity gx,gy,gz)"
            ),
        )
    axes = gravity.frame if config.align == "manhattan" else None
    if config.align == "manhattan" and axes is None:
        warning = warning or "no room axes in this depth map; cuboids are gravity-aligned with a free yaw"
    return gravity, Alignment(config.align, gravity.up, axes), warning


def grid_assignment(prep: FitInput, labels: np.ndarray) -> np.ndarray:
    """Per fitting-grid cell label (Hs, Ws) from the labels (N,) of a frame's fitting points: cuboid
    index, -1 none, -2 occluded, -3 no depth."""
    grid = prep.grid
    out = np.full(grid.shape[0] * grid.shape[1], INVALID, dtype=np.int32)
    out[as_kind(grid.index, out)] = labels
    return out.reshape(grid.shape)

"""A frame's fitting points and what surrounds the estimator's loop: the fitting grid of a depth map
(:func:`prepare_points`), the orientation constraint from gravity (:func:`resolve_alignment`), and the
per-cell labels of the selected cuboids (:func:`grid_assignment`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import torch

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.align import Alignment
from cuboidcli.fitting.assign import OCCLUDED, assign_points
from cuboidcli.fitting.backend import backend_for
from cuboidcli.fitting.config import FitConfig
from cuboidcli.geometry.cells import ImageCells
from cuboidcli.geometry.gravity import Gravity, estimate_gravity, given_gravity, manhattan_axes
from cuboidcli.sampling import SpaceCells

#: Label of a fitting-grid cell without depth (:func:`grid_assignment`).
INVALID = -3


@dataclass
class PreparedPoints:
    points: torch.Tensor  # (N, 3) float32, metres
    grid_index: torch.Tensor  # (N,) flat index into the fitting grid
    grid_shape: tuple[int, int]
    depth_grid: torch.Tensor  # (Hs, Ws) metres, 0 = invalid
    focal_cells: tuple[float, float] | None = None  # (fx, fy) / grid_step: focal lengths in grid cells
    grid_step: int = 8
    cells: ImageCells | None = None  # the points binned by grid cell (scoring visits the cells it can reach)
    space: SpaceCells | None = None  # unorganised points (a room): the voxel cells localised sets search


def prepare_points(
    depth_m: np.ndarray, camera: Camera, grid_step: int, device: str = "cpu"
) -> PreparedPoints:
    """The fitting grid: every grid_step-th pixel (nearest, no averaging), invalid depth excluded."""
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
    return PreparedPoints(
        points=torch.from_numpy(flat[ok].astype(np.float32)).to(device),
        grid_index=torch.from_numpy(ok),
        grid_shape=depth_grid.shape,
        depth_grid=torch.from_numpy(depth_grid.astype(np.float32)).to(device),
        focal_cells=(camera.fx / grid_step, camera.fy / grid_step),
        grid_step=grid_step,
        cells=cells,
    )


def resolve_alignment(
    prep: PreparedPoints, config: FitConfig
) -> tuple[Gravity | None, Alignment | None, str]:
    """Gravity and the orientation constraint of a fit: (gravity or None, alignment or None, warning).

    A given ``config.gravity_down`` is used as it is; otherwise gravity is estimated from the depth map
    when ``config.align`` needs it (geometry/gravity.py). "manhattan" also needs the room's horizontal
    axes, estimated from the surface normals and made exactly perpendicular to the gravity used. Without
    a reliable gravity the fit stays free, with a warning.
    """
    if config.align == "free" and config.gravity_down is None:
        return None, None, ""
    hs, ws = prep.grid_shape
    grid = np.zeros((hs * ws, 3))
    grid[prep.grid_index.numpy()] = prep.points.double().cpu().numpy()
    grid = grid.reshape(hs, ws, 3)
    estimated = estimate_gravity(grid, seed=config.seed)
    if config.gravity_down is not None:
        gravity = given_gravity(config.gravity_down)
        if estimated is not None:  # keep the room's axes for "manhattan", made vertical for the given down
            gravity = Gravity(
                gravity.down, "given", 1.0, manhattan_axes(gravity.down, estimated.frame), estimated.support
            )
    else:
        gravity = estimated
    if config.align == "free":
        return gravity, None, ""
    if gravity is None:
        return (
            None,
            None,
            (
                f"no reliable gravity in this depth map (too few floor, wall or table surfaces); "
                f"cuboids are fitted free instead of {config.align}-aligned (give --gravity gx,gy,gz)"
            ),
        )
    axes = gravity.frame if config.align == "manhattan" else None
    warning = ""
    if config.align == "manhattan" and axes is None:
        warning = "no room axes in this depth map; cuboids are gravity-aligned with a free yaw"
    return gravity, Alignment(config.align, gravity.up, axes), warning


def grid_assignment(
    prep: PreparedPoints, state: np.ndarray, cuboids: list[Cuboid], config: FitConfig
) -> np.ndarray:
    """Per fitting-grid cell label (Hs, Ws): cuboid index, -1 none, -2 occluded, -3 no depth; the values
    come from the fit's backend (``config.backend`` on the points' device)."""
    labels = np.full(prep.grid_shape[0] * prep.grid_shape[1], INVALID, dtype=np.int32)
    lab = assign_points(
        prep.points,
        cuboids,
        config.tau_sq_m2,
        config.beta,
        config.tau_c,
        config.occlusion_aware,
        backend_for(config.backend, prep.points.device),
    )
    if state is not None and len(cuboids):
        lab[state < 0] = OCCLUDED
    labels[prep.grid_index.numpy()] = lab
    return labels.reshape(prep.grid_shape)

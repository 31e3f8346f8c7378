"""What the estimator fits: one :class:`FitInput` for a frame and for a room.

A frame (a depth map, or a photo's estimated depth) gives its fitting points on an image grid, seen from
one camera at the origin; a room (a scan, a fused sequence, an array of points) gives voxel means, each
seen from the camera that observed it or from a virtual viewpoint outside its surface. The estimator
(:func:`cuboidcli.fitting.pipeline.estimate`) runs the same loop on both; what differs is carried here:

- ``grid``: the image grid of a frame's points (localised minimal sets search it, the learned sampler
  weighs it, the labels are drawn on it); None for a room, whose localised sets search ``space`` instead;
- ``views``: how visibility is defined: ``camera`` (one camera at the origin), ``cameras`` (a camera per
  point) or ``none`` (no camera saw the points: a bare cloud);
- ``backend``: the scoring kernels: None for a frame (chosen from ``FitConfig.backend`` and the device),
  a room's own (:class:`~cuboidcli.fitting.room_backend.RoomBackend`), which knows how its points were seen;
- the orientation constraint (``alignment``) and the direction of gravity, found while preparing.

:func:`cuboidcli.fitting.prepare.frame_input` and :func:`cuboidcli.fitting.room.room_input` make one.
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from typing import TYPE_CHECKING

import numpy as np

from cuboidcli.fitting.align import Alignment
from cuboidcli.fitting.backend import ScoringBackend
from cuboidcli.geometry.arrays import is_tensor
from cuboidcli.geometry.cells import ImageCells
from cuboidcli.geometry.cloud import RoomUp
from cuboidcli.geometry.gravity import Gravity
from cuboidcli.sampling import SpaceCells

if TYPE_CHECKING:
    from torch import Tensor

#: The kinds of input, each with its defaults (:data:`cuboidcli.fitting.config.KIND_DEFAULTS`).
KINDS = ("frame", "room")
#: How the fitting points were seen (:attr:`FitInput.views`).
VIEWS = ("camera", "cameras", "none")


@dataclass
class ImageGrid:
    """A depth map's fitting grid: every ``step``-th pixel in each direction; ``index`` and ``depth`` of the
    points' kind (numpy arrays or tensors)."""

    index: Tensor
    """(N,) flat index of each fitting point in the grid (cells without depth hold no point)."""
    shape: tuple[int, int]
    """(Hs, Ws) cells."""
    depth: Tensor
    """(Hs, Ws) metres, 0 where invalid."""
    step: int
    """Pixels between grid cells."""
    focal_cells: tuple[float, float]
    """(fx, fy) / step: the focal lengths in grid cells."""
    cells: ImageCells
    """The points binned by grid cell: scoring visits only the cells a box can reach."""


@dataclass
class RoomFitting:
    """How a room's points became its fitting points."""

    voxel_m: float
    """Side of the voxels whose means are the fitting points (grown from ``FitConfig.voxel_m`` where a
    room gives more than ``fit_points``)."""
    visibility: str
    """The scoring kernels' mode: views, inside or plain."""
    up: RoomUp
    """The room's up direction and Manhattan axes, and where they came from."""
    order: np.ndarray
    """(M,) the voxel of each fitting point (the points are sorted into scoring blocks)."""
    inverse: np.ndarray
    """(N,) the voxel of each input point."""
    colors: np.ndarray | None = None
    """(M,) x 3 float64 the mean colour (0-255) of each fitting point's input points, in scoring order; None
    when the input has no colours."""


@dataclass
class FitInput:
    """The fitting points and what is known about how they were seen (module docstring)."""

    kind: str
    """``frame`` or ``room``."""
    points: Tensor
    """(N, 3) float32 metres: a frame's in the OpenCV camera frame, a room's in its own world frame. A numpy
    array (the default parts on the CPU: no torch needed) or a tensor (a GPU, a part that computes with
    torch)."""
    views: str
    """camera, cameras or none (:data:`VIEWS`)."""
    grid: ImageGrid | None = None
    space: SpaceCells | None = None
    """A room's voxel cells, where localised minimal sets find the ball around their first point."""
    backend: ScoringBackend | None = None
    """The scoring kernels; None = ``FitConfig.backend`` on the points' device."""
    alignment: Alignment | None = None
    """The orientation constraint of the selected cuboids (None = free)."""
    down: np.ndarray | None = None
    """(3,) unit gravity, None when unknown (a frame's kinds then take the camera's y as down)."""
    viewpoint: np.ndarray | None = None
    """(3,) where the room's shell is seen from: None = the camera at the origin (a frame)."""
    gravity: Gravity | None = None
    """A frame's gravity as estimated or given (its source and support go into the result)."""
    room: RoomFitting | None = None
    warnings: list[str] = field(default_factory=list)
    timing_s: dict = field(default_factory=dict)
    """Seconds of the preparation's stages (prepare, gravity)."""
    started: float = 0.0
    """time.perf_counter() when the preparation began: the fit's total counts from there."""

    @property
    def n(self) -> int:
        return int(self.points.shape[0])

    def as_tensors(self) -> FitInput:
        """This input with its points and grid as CPU tensors (itself if they are tensors already): for the
        parts and backends that compute with torch."""
        if is_tensor(self.points):
            return self
        import torch

        grid = self.grid
        if grid is not None:
            grid = replace(grid, index=torch.from_numpy(grid.index), depth=torch.from_numpy(grid.depth))
        return replace(self, points=torch.from_numpy(self.points), grid=grid)

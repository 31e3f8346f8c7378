"""The objects the fitting loop hands from one stage to the next once a step has its winner:

- :class:`Box`: one cuboid as arrays (numpy, or tensors) with a leading axis of one box;
- :class:`Scored`: a box with its values at every point, its inlier-count gain and how it was aligned;
- :class:`StepContext`: what every stage of one step reads (the points, the state of the cuboids selected
  so far, the inlier function's parameters, the settings, the scoring backend and the random generator).

The slab rule (:func:`thin_axis`), the line rule (:func:`not_lines`) and the robust extent of points
(:data:`ROBUST_PERCENTILES`) are here too: growing, aligning and the room-shell rule use them.
"""

from __future__ import annotations

from dataclasses import dataclass
from typing import TYPE_CHECKING, Any

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.backend import ScoringBackend, backend_for
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.scoring import ScoreParams
from cuboidcli.geometry import arrays
from cuboidcli.geometry.arrays import device_of, indices, numpy64
from cuboidcli.geometry.inlier import INLIER_CUT, combine

if TYPE_CHECKING:
    from torch import Tensor

SLAB_RATIO = 0.25
"""A box is a slab (a wall, a floor, a ceiling, a table top) when its thinnest half-size is under this share
of its middle one (:func:`thin_axis`)."""

ROBUST_PERCENTILES = (1.0, 99.0)
"""Where points end along an axis: their 1st and 99th percentiles, so that a few stray points (flying
pixels at depth edges, a reflection) do not stretch a box fitted to them."""


LINE_SHARE = 0.1
"""A box whose two smaller half-sizes are both under this share of the inlier threshold tau (m; 6.3 mm at
the default tau) is a line, not a box (:func:`not_lines`). Six points along a row of chair seats or a
table's edge make the solver shrink two of the box's sides to its lower bound; the line then explains the
points within tau of it, occludes nothing, and won a step in long rows of furniture (1-3 of the cuboids of
scene0004_00, a room of chairs, at seeds 0-4, each 4 m long). A cuboid abstracts a surface or a solid; a
line explains neither."""


def not_lines(half_sizes, tau_sq_m2: float) -> np.ndarray:
    """(H,) bool: the boxes of ``half_sizes`` (H, 3) that are not lines (:data:`LINE_SHARE`)."""
    half = np.sort(numpy64(half_sizes), axis=1)
    return half[:, 1] >= LINE_SHARE * float(np.sqrt(tau_sq_m2))


@dataclass(frozen=True)
class Box:
    """One cuboid as the fitting loop holds it: (1, 3) ``center`` and (1, 3) ``half`` sizes in metres and a
    (1, 3, 3) ``rotation`` whose columns are the cuboid's axes, in the points' frame (a frame's: the OpenCV
    camera's), of their kind (numpy arrays or tensors) and on their device. The dtype is the solver's
    (float32 for a frame's points); the leading axis of one box lets the backend's batched kernels take a
    box as it is."""

    center: Tensor
    half: Tensor
    rotation: Tensor

    @classmethod
    def from_numpy(cls, center: np.ndarray, half: np.ndarray, rotation: np.ndarray, like: Tensor) -> Box:
        """The box of (3,) ``center``, (3,) ``half`` and (3, 3) ``rotation`` arrays, of the kind, on the
        device and in the dtype of ``like``."""
        return cls(*(arrays.like(x[None], like) for x in (center, half, rotation)))

    def numpy(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(center (3,), half (3,), rotation (3, 3)) as float64 arrays."""
        return tuple(numpy64(x[0]) for x in (self.center, self.half, self.rotation))

    def thin_axis(self) -> int:
        """The box's slab axis (:func:`thin_axis` of its half-sizes as they are), or -1."""
        return thin_axis(numpy64(self.half[0]))

    def to_cuboid(self, gain: float) -> Cuboid:
        """The selected box as a :class:`~cuboidcli.cuboid.Cuboid` with its inlier-count gain."""
        return Cuboid(*self.numpy(), inlier_gain=gain)


@dataclass(frozen=True)
class Scored:
    """A box with what the fit knows of it."""

    box: Box
    values: Tensor
    """(N,) float64: f_OAI of the box on its own at every point (not joined with the state)."""
    gain: float
    """Inlier-count gain of the box over the step's state."""
    kind: str = "free"
    """How the box was aligned (:func:`cuboidcli.fitting.align.align_winner`): "manhattan", "gravity",
    "tilted" or "free"."""


@dataclass(frozen=True)
class StepContext:
    """What the stages of one step read: ``points`` (N, 3) and ``state`` (N,) float64, the f_OAI of the
    cuboids selected so far, of one kind on one device; the inlier function's ``sp``; the ``config``; the
    ``backend`` that computes values, gains and refinements; the ``generator`` (numpy's for numpy arrays,
    torch's for tensors) that draws the refinement's subset of inliers."""

    points: Tensor
    state: Tensor
    sp: ScoreParams
    config: FitConfig
    backend: ScoringBackend
    generator: Any

    @classmethod
    def of(
        cls,
        points: Tensor,
        state: Tensor,
        config: FitConfig,
        sp: ScoreParams | None = None,
        backend: ScoringBackend | None = None,
        generator=None,
    ) -> StepContext:
        """A context with defaults for what is left out: the config's inlier function, the backend
        ``config.backend`` names on the points' device, a generator of the points' kind seeded with
        ``config.seed``."""
        return cls(
            points,
            state,
            sp or score_params(config),
            config,
            backend or backend_for(config.backend, device_of(points)),
            generator if generator is not None else arrays.generator(config.seed, points),
        )

    def values(self, box: Box) -> Tensor:
        """f_OAI of ``box`` at every point (N,), float64."""
        return self.backend.values(self.points, box.center, box.half, box.rotation, self.sp)[0]

    def gain_of(self, values: Tensor) -> float:
        """Inlier-count gain of a box with ``values`` over the state."""
        return gain_of(values, self.state)

    def score(self, box: Box, kind: str = "free") -> Scored:
        """``box`` with its values and their gain."""
        values = self.values(box)
        return Scored(box, values, self.gain_of(values), kind)

    def gain(self, box: Box) -> float:
        """The gain of ``box`` from the backend's scoring loop, which visits only the points the box can
        reach (its values are not computed)."""
        return float(
            self.backend.gains(self.points, box.center, box.half, box.rotation, self.state, self.sp)[0]
        )

    def newly_explained(self, values: Tensor) -> Tensor:
        """Indices (M,) of the points a box with ``values`` makes inliers (:data:`INLIER_CUT`) that the
        state explains less well."""
        return indices((values >= INLIER_CUT) & (values > self.state))


def score_params(config: FitConfig) -> ScoreParams:
    """The inlier function's parameters of ``config``."""
    return ScoreParams.of(config)


def values_one(pts, c, a, R, sp: ScoreParams, backend: ScoringBackend | None = None) -> Tensor:
    """f_OAI of one cuboid ((1, 3) centre, (1, 3) half-sizes, (1, 3, 3) rotation) at every point (N,),
    float64, computed by ``backend`` (None: the default backend of the points' device)."""
    return (backend or backend_for("auto", device_of(pts))).values(pts, c, a, R, sp)[0]


def gain_of(values: Tensor, state: Tensor) -> float:
    """Inlier-count gain of one cuboid with per-point values f_OAI ``values`` over the current ``state``."""
    return float((combine(values, state) - state).sum())


def thin_axis(half: np.ndarray) -> int:
    """The thickness axis of a slab (its thinnest axis, under :data:`SLAB_RATIO` of its middle one) with
    half-sizes ``half`` (3,), or -1 for a box that is not a slab."""
    order = np.argsort(half)
    return int(order[0]) if half[order[0]] < SLAB_RATIO * half[order[1]] else -1

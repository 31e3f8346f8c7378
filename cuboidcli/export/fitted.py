"""What the writers read from a fitted frame or room: one shape for both, so that one writer serves both.

A frame's result holds its depth map (and image); a room's holds its input points with their cuboid labels,
its whole objects and the sequence frames its overlays may be drawn on. The export layer reads these by
attribute (:class:`Fitted`) and never imports the layers that make them; :class:`FittedData` is a plain
holder for callers that have the pieces at hand (a saved result read back, a test).
"""

from __future__ import annotations

import os
from dataclasses import dataclass, field
from typing import Protocol

import numpy as np

from cuboidcli.cuboid import Cuboid
from cuboidcli.io.result import FitResult


class View(Protocol):
    """A frame of a room's sequence, seen by the result's depth camera (``record.camera``)."""

    @property
    def name(self) -> str: ...

    @property
    def world_from_camera(self) -> np.ndarray:
        """(4, 4) camera -> the room's input frame (OpenCV camera axes), metres."""

    @property
    def depth_path(self) -> str | os.PathLike: ...

    @property
    def rgb_path(self) -> str | os.PathLike | None: ...

    @property
    def depth_scale(self) -> float:
        """Metres per unit of the depth image."""


class Fitted(Protocol):
    """A fitted frame (``record.frame`` "opencv") or room ("world"), as the writers read it."""

    @property
    def record(self) -> FitResult:
        """The "cuboids/1" record; ``camera`` is None for a bare scan."""

    @property
    def depth_m(self) -> np.ndarray | None:
        """(H, W) float32 metres of a frame; None for a room (or a saved frame whose map is gone)."""

    @property
    def rgb(self) -> np.ndarray | None:
        """(H, W, 3) uint8 or None."""

    @property
    def points(self) -> np.ndarray | None:
        """(N, 3) float64: a room's input points in its world frame; None for a frame."""

    @property
    def point_labels(self) -> np.ndarray | None:
        """(N,) int32 per room point: cuboid index, -1 none, -2 hidden; None for a frame."""

    @property
    def objects(self) -> list[Cuboid]:
        """A room's whole-object boxes (empty for a frame)."""

    @property
    def up(self) -> np.ndarray | None:
        """(3,) unit up direction in the result's frame, or None."""

    @property
    def views(self) -> list[View]:
        """The sequence frames a room's overlays may be drawn on ([] for a frame or a bare scan)."""


def result_up(result: FitResult) -> np.ndarray | None:
    """The up direction (3,) in the result's frame of a result with a "gravity" entry, else None."""
    down = (result.extras.get("gravity") or {}).get("down")
    if down is None:
        return None
    v = -np.asarray(down, dtype=np.float64)
    if v.shape != (3,) or not np.all(np.isfinite(v)) or np.linalg.norm(v) < 1e-9:
        raise ValueError("the result's gravity.down must be three finite numbers, not all zero")
    return v / np.linalg.norm(v)


@dataclass
class FittedData:
    """A :class:`Fitted` made of the pieces themselves."""

    record: FitResult
    depth_m: np.ndarray | None = None
    rgb: np.ndarray | None = None
    points: np.ndarray | None = None
    point_labels: np.ndarray | None = None
    objects: list[Cuboid] = field(default_factory=list)
    up: np.ndarray | None = None
    views: list[View] = field(default_factory=list)

    @classmethod
    def of_record(
        cls, record: FitResult, *, depth_m: np.ndarray | None = None, rgb: np.ndarray | None = None
    ) -> FittedData:
        """A saved result with the depth map and image it was fitted on, where they are at hand; up is the
        record's gravity (a room's points, objects and frames are not in its record)."""
        return cls(record, depth_m, rgb, up=result_up(record))

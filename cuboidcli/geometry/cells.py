"""Points binned by the cells of an image grid (:class:`ImageCells`), and the numba helpers that find the
rows and columns of the grid a box can reach, so that scoring visits only those (:mod:`.fused`)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from numba import njit


@njit(cache=True, inline="always")
def _index_range(coords, lo, hi):
    """First and last index of the increasing ``coords`` within [lo, hi], widened by one on each side for
    rounding (the points' own x/z, y/z are tested again inside); (1, 0) when none is."""
    i0 = np.searchsorted(coords, lo) - 1
    i1 = np.searchsorted(coords, hi, side="right")
    return max(i0, 0), min(i1, coords.shape[0] - 1)


@njit(cache=True, inline="always")
def grid_reach(t0, t1, t2, rad, col_u, row_v):
    """Rows and columns of the image grid whose lines of sight may meet the cube of half-side ``rad``
    around (t0, t1, t2): (r_lo, r_hi, c_lo, c_hi), the whole grid when the cube reaches z <= 0."""
    z_near = t2 - rad
    if z_near <= 1e-6:
        return 0, row_v.shape[0] - 1, 0, col_u.shape[0] - 1
    z_far = t2 + rad
    u_lo = min((t0 - rad) / z_near, (t0 - rad) / z_far)
    u_hi = max((t0 + rad) / z_near, (t0 + rad) / z_far)
    v_lo = min((t1 - rad) / z_near, (t1 - rad) / z_far)
    v_hi = max((t1 + rad) / z_near, (t1 + rad) / z_far)
    c_lo, c_hi = _index_range(col_u, u_lo, u_hi)
    r_lo, r_hi = _index_range(row_v, v_lo, v_hi)
    return r_lo, r_hi, c_lo, c_hi


@njit(cache=True, inline="always")
def box_sum(sat, cols, r0, r1, c0, c1):
    """Sum of the per-cell values over rows r0..r1 and columns c0..c1 from their summed-area table."""
    if r1 < r0 or c1 < c0:
        return 0.0
    w = cols + 1
    return sat[(r1 + 1) * w + c1 + 1] - sat[r0 * w + c1 + 1] - sat[(r1 + 1) * w + c0] + sat[r0 * w + c0]


@dataclass(frozen=True)
class ImageCells:
    """Points binned by the cells of an image grid (row-major), so that a hypothesis visits only the cells
    its lines of sight and near zone reach.

    ``start`` (rows * cols + 1,) int64: the points of cell k are ``start[k]:start[k + 1]`` (the points are
    sorted by cell); ``col_u`` (cols,) and ``row_v`` (rows,): the normalised image coordinates x/z, y/z of
    the columns and rows, increasing."""

    start: np.ndarray
    col_u: np.ndarray
    row_v: np.ndarray

    @classmethod
    def of_grid(cls, cell_of_point: np.ndarray, col_u: np.ndarray, row_v: np.ndarray) -> ImageCells:
        """Cells of a fitting grid: ``cell_of_point`` (N,) the flat cell index of each point, increasing."""
        cells = np.asarray(cell_of_point, dtype=np.int64)
        if cells.size > 1 and np.any(np.diff(cells) < 0):
            raise ValueError("points must be sorted by their cell")
        n_cells = len(row_v) * len(col_u)
        start = np.searchsorted(cells, np.arange(n_cells + 1)).astype(np.int64)
        return cls(start, np.ascontiguousarray(col_u, np.float64), np.ascontiguousarray(row_v, np.float64))

    @property
    def shape(self) -> tuple[int, int]:
        return len(self.row_v), len(self.col_u)

    def subgrid(self, row_step: int, col_step: int) -> tuple[np.ndarray, ImageCells]:
        """The points on every ``row_step``-th row and ``col_step``-th column: (indices, their cells)."""
        rows, cols = self.shape
        cell = np.repeat(np.arange(rows * cols), np.diff(self.start))
        r, c = np.divmod(cell, cols)
        keep = np.flatnonzero((r % row_step == 0) & (c % col_step == 0))
        sub_cols = self.col_u[::col_step]
        sub_cell = (r[keep] // row_step) * len(sub_cols) + c[keep] // col_step
        return keep, ImageCells.of_grid(sub_cell, sub_cols, self.row_v[::row_step])

    def summed_area(self, per_point: np.ndarray) -> np.ndarray:
        """Summed-area table ((rows + 1) * (cols + 1),) of ``per_point`` summed per cell."""
        rows, cols = len(self.row_v), len(self.col_u)
        csum = np.concatenate([[0.0], np.cumsum(per_point, dtype=np.float64)])
        per_cell = (csum[self.start[1:]] - csum[self.start[:-1]]).reshape(rows, cols)
        sat = np.zeros((rows + 1, cols + 1))
        sat[1:, 1:] = per_cell.cumsum(0).cumsum(1)
        return sat.ravel()

"""The scoring backend of a whole room: the estimator's usual interface (:class:`ScoringBackend`) over the
kernels of :mod:`cuboidcli.geometry.room`, which know how the room's points were seen (``views``,
``inside`` or ``plain``; docs/scenes.md).

The estimator (:func:`cuboidcli.fitting.pipeline.fit_points`) takes this backend in place of the frame's,
so sampling, solving, selection, refinement, growing and alignment are the same code for a frame and for
a room; only the value of a point for a cuboid differs. The backend is bound to one set of points in
block order (:class:`~cuboidcli.geometry.room.RoomPoints`): every tensor of points it is handed is that
set, or the subset of it :meth:`RoomBackend.select_best` nominates on.

The points are numpy arrays (the default parts on the CPU: no torch is imported) or CPU tensors (a part
that computes with torch, such as the neural solver); what the backend gives back is of the points' kind.
"""

from __future__ import annotations

from contextlib import contextmanager
from typing import TYPE_CHECKING

import numba
import numpy as np

from cuboidcli.fitting.backend import NOMINATED, PRUNE_MARGIN, ScoringBackend
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.scoring import ScoreParams
from cuboidcli.geometry.arrays import as_kind, is_tensor, on_cpu_as
from cuboidcli.geometry.room import RoomPoints, room_gains, room_params, room_values
from cuboidcli.geometry.room_refine import refine_surface_adam
from cuboidcli.geometry.rotations import axis_angle_to_matrix, matrix_to_axis_angle

if TYPE_CHECKING:
    from torch import Tensor

#: Nomination scores every hypothesis on every NOMINATION_STEP-th point of each block (at least one) ...
#: (The nominees only set the exact pass's threshold: any step selects the same cuboids. On the real scans
#: 16 scored a cluttered room in 6.66 s against 7.09 s with 8; 24 gained little more, 6.56 s.)
NOMINATION_STEP = 16
#: ... this many hypotheses at a time, each chunk pruned by the nominees of the chunks before it ...
NOMINATION_CHUNK = 256
#: ... on the subset grouped into blocks of 1 m split by viewpoint cells of 2 m (the room's own blocks are
#: 0.5 m by 0.5 m): on a cluttered real scan the nomination took 0.045 s a selection against 0.069 s.
NOMINATION_BLOCKS = (1.0, 2.0)


def refine_surface(
    points: Tensor, center: Tensor, half: Tensor, rotation: Tensor, a_min: float, a_max: float,
    iters: int = FitConfig.refine_iters, lr: float = FitConfig.refine_lr,
) -> tuple[Tensor, Tensor, Tensor]:  # fmt: skip
    """Adam on the mean squared distance of ``points`` (M, 3) to the surface of the cuboid (center (3,),
    half (3,), rotation (3, 3)), half-sizes kept in [a_min, a_max]; the best iterate. A room's points have
    no single camera, so the frame's occlusion-aware distance (the nearest face seen from the origin) is
    replaced by the plain distance to the nearest face, which is what the inliers of a box's surface
    minimise from any viewpoint. Tensors only (the reference for :func:`refine_surface_fused`)."""
    import torch

    from cuboidcli.geometry import kernels as K

    pts = points.double()
    x = torch.cat([center.double(), matrix_to_axis_angle(rotation.double()), half.double()])
    m, v = torch.zeros_like(x), torch.zeros_like(x)
    best = (float("inf"), center.double(), half.double(), rotation.double())
    b1, b2, eps = 0.9, 0.999, 1e-8
    # Adam written out: torch.optim's per-call set-up costs more than the few steps on ~1k points
    with torch.enable_grad():
        for it in range(iters + 1):
            x = x.detach().requires_grad_(True)
            R = axis_angle_to_matrix(x[3:6])[None]
            local = K.to_local(pts, x[None, :3], R)
            loss = K.cuboid_sq_distance(local, x[None, 6:]).mean()
            if loss.item() < best[0]:
                best = (loss.item(), x[:3].detach().clone(), x[6:].detach().clone(), R[0].detach().clone())
            if it == iters:
                break
            (g,) = torch.autograd.grad(loss, x)
            with torch.no_grad():
                m = b1 * m + (1 - b1) * g
                v = b2 * v + (1 - b2) * g * g
                step = lr * (m / (1 - b1 ** (it + 1))) / ((v / (1 - b2 ** (it + 1))).sqrt() + eps)
                x = x - step
                x[6:] = x[6:].clamp(a_min, a_max)
    _, cb, ab, Rb = best
    return cb.to(center.dtype), ab.to(half.dtype), Rb.to(rotation.dtype)


def refine_surface_fused(
    points: Tensor, center: Tensor, half: Tensor, rotation: Tensor, a_min: float, a_max: float,
    iters: int = FitConfig.refine_iters, lr: float = FitConfig.refine_lr,
) -> tuple[Tensor, Tensor, Tensor]:  # fmt: skip
    """:func:`refine_surface` in one numba loop (the same Adam; the rotation's gradient by central
    differences): numpy arrays or tensors in, float64 out, of the kind of ``points``."""
    # the rotation converted in the points' kind (torch's and numpy's functions may round apart)
    r = _np64(matrix_to_axis_angle(as_kind(_np64(rotation), points)))
    init = np.concatenate([_np64(center), r, _np64(half)])
    best = refine_surface_adam(_np64(points), init, float(a_min), float(a_max), lr, iters)
    c, a, r = (as_kind(x.copy(), points) for x in (best[:3], best[6:], best[3:6]))
    return c, a, axis_angle_to_matrix(r)


class RoomBackend(ScoringBackend):
    """Values and gains of cuboids against a room's points (:class:`RoomPoints`, block order), with
    provable pruning per block; refinement on the plain surface distance (:func:`refine_surface_fused`,
    the numba form of :func:`refine_surface`). CPU."""

    name = "room"
    prunes = True

    def __init__(self, room: RoomPoints) -> None:
        self.room = room
        self._sub_index, self._sub = room.subsample(NOMINATION_STEP)
        # The nomination's subset in coarser blocks: with the room's own blocks it holds one or two points a
        # block, and a hypothesis spent most of its time deciding which blocks it reaches. Which blocks the
        # nominees' gains are summed in changes no cuboid: the full pass is exact whatever the nominees.
        views = self._sub.views if room.visibility == "views" else None
        self._nom = RoomPoints.build(self._sub.points, views, room.visibility, *NOMINATION_BLOCKS)
        self._nom_index = self._sub_index[self._nom.order]
        self._bound_cache: tuple | None = None

    def _points_of(self, points: Tensor) -> tuple[RoomPoints, np.ndarray | None]:
        n = points.shape[0]
        if n == self.room.points.shape[0]:
            return self.room, None
        if n == self._sub.points.shape[0]:
            return self._sub, self._sub_index
        raise ValueError(f"a room backend scores its own {self.room.points.shape[0]} points, not {n}")

    @staticmethod
    def _params(sp: ScoreParams) -> tuple:
        return room_params(sp.tau, sp.beta, sp.tau_c)

    def values(self, points, centers, half_sizes, rotations, sp: ScoreParams) -> Tensor:
        room, _ = self._points_of(points)
        boxes = [_np64(x) for x in (centers, half_sizes, rotations)]
        with _one_thread_if(len(boxes[0]) * room.points.shape[0] <= SERIAL_PAIRS):
            return on_cpu_as(room_values(room, *boxes, self._params(sp)), points)

    def gains(
        self, points, centers, half_sizes, rotations, state, sp: ScoreParams, prune_below=-np.inf, cells=None
    ) -> np.ndarray:
        room, _ = self._points_of(points)
        st = _np64(state)
        boxes = [_np64(x) for x in (centers, half_sizes, rotations)]
        bound, order, held = self._bound_of(room, st)
        with _one_thread_if(len(boxes[0]) == 1):
            return room_gains(room, st, *boxes, self._params(sp), prune_below, bound, order, held)

    def _bound_of(self, room: RoomPoints, state: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(:meth:`RoomPoints.block_bound` of ``state``, the blocks by that bound, largest first, and
        :meth:`RoomPoints.block_held` of ``state``), kept for
        the last (points, state) pair: a step scores the winner's face moves, thousands of calls of one
        box each in a room, against one state (compared by content, so a state changed in place or
        handed over again as another array is not mistaken for the last)."""
        cached = self._bound_cache
        if cached is not None and cached[0] is room and np.array_equal(cached[1], state):
            return cached[2:]
        bound = room.block_bound(state)
        order = np.argsort(-bound, kind="stable")
        held = room.block_held(state)
        self._bound_cache = (room, state.copy(), bound, order, held)
        return bound, order, held

    def refine(
        self, points, center, half, rotation, a_min: float, a_max: float,
        iters: int = FitConfig.refine_iters, lr: float = FitConfig.refine_lr,
    ):  # fmt: skip
        return refine_surface_fused(points, center, half, rotation, a_min, a_max, iters, lr)

    def select_best(
        self, points, centers, half_sizes, rotations, state, sp: ScoreParams, generator,
        prescore_points: int = 0, rescore_top: int = 64,
    ) -> tuple[int, float, Tensor]:  # fmt: skip
        """Exact selection: every hypothesis is scored on a regular subset of each block's points, the best
        exact gain of the ``NOMINATED`` best of them becomes the pruning threshold, and the full pass
        abandons hypotheses that provably stay below it. (The approximate ``prescore_points`` path of a
        frame has no use here: pruning by blocks already skips what a hypothesis cannot reach.)

        The nomination itself prunes: hypotheses are scored on the subset in chunks of
        :data:`NOMINATION_CHUNK`, and each chunk abandons those that provably stay below the
        ``NOMINATED``-th best subset gain of the chunks before it, which cannot be nominated (the same
        nominees as scoring all of them; on real scans it scores about a fifth of the subset's points)."""
        params = self._params(sp)
        st = _np64(state)
        c, a, R = (_np64(x) for x in (centers, half_sizes, rotations))
        sub_state = st[self._nom_index]
        sub_bound = self._nom.block_bound(sub_state)
        sub_order = np.argsort(-sub_bound, kind="stable")
        sub_held = self._nom.block_held(sub_state)
        g_sub = np.full(len(c), -np.inf)
        floor = -np.inf
        for s in range(0, len(c), NOMINATION_CHUNK):
            e = min(s + NOMINATION_CHUNK, len(c))
            g_sub[s:e] = room_gains(
                self._nom, sub_state, c[s:e], a[s:e], R[s:e], params, floor, sub_bound, sub_order, sub_held
            )
            if e >= NOMINATED:
                floor = float(np.partition(g_sub[:e], -NOMINATED)[-NOMINATED]) - PRUNE_MARGIN
        top = np.argsort(-g_sub, kind="stable")[:NOMINATED]
        bound, order, held = self._bound_of(self.room, st)
        g_top = room_gains(self.room, st, c[top], a[top], R[top], params, bound=bound, order=order, held=held)
        threshold = float(g_top.max()) - PRUNE_MARGIN
        # the nominees' exact gains are known: the full pass scores the others (each hypothesis is summed
        # alone, in the same block order, so a gain is the same number from either call)
        rest = np.ones(len(c), dtype=bool)
        rest[top] = False
        g = np.empty(len(c))
        g[top] = g_top
        g[rest] = room_gains(self.room, st, c[rest], a[rest], R[rest], params, threshold, bound, order, held)
        best = int(np.argmax(g))
        return best, float(g[best]), on_cpu_as(g, points)


#: Values of at most this many (box, point) pairs are computed on one thread (about 2 ms of work).
SERIAL_PAIRS = 1 << 17


@contextmanager
def _one_thread_if(small: bool):
    """numba's threads for a call: one where ``small``. A parallel loop waits for all its threads, and on a
    loaded machine a call of a millisecond or two then often waits for a thread the system has put aside:
    the values of one wall box on 35,000 points took a median 34 ms on two threads against 1.7 ms on one,
    the gains of one box (the loop runs over boxes, so one thread works anyway) 15 ms against 1 ms. The
    numbers computed are the same."""
    if not small:
        yield
        return
    threads = numba.get_num_threads()
    numba.set_num_threads(1)
    try:
        yield
    finally:
        numba.set_num_threads(threads)


_WARM = False


def warm_up_room() -> None:
    """Compile (or load from numba's cache) the room kernels of every visibility and the surface
    refinement, once per process, on tiny inputs (the parts of a fit warm up their own kernels)."""
    global _WARM
    if _WARM:
        return
    p = np.array([[0.0, 0.0, 2.0], [0.1, 0.0, 2.0], [0.2, 0.1, 2.0]])
    c, a, R = np.array([[0.0, 0.0, 2.5]]), np.full((1, 3), 0.5), np.eye(3)[None]
    params = room_params(0.004, 5.0, 0.008)
    for vis in ("views", "inside", "plain"):
        room = RoomPoints.build(p, np.zeros_like(p), vis)
        room_gains(room, np.zeros(3), c, a, R, params)
        room_values(room, c, a, R, params)
    refine_surface_fused(p, p[0], np.full(3, 0.1), np.eye(3), 1e-3, 1.0)
    _WARM = True


def _np64(x) -> np.ndarray:
    if is_tensor(x):
        x = x.detach().cpu().double().numpy()
    return np.ascontiguousarray(x, dtype=np.float64)

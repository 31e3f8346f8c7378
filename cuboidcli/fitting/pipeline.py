"""The estimator (paper Sec. 3.2, Fig. 3): sample minimal sets -> solve -> score -> select, one cuboid
per step, until the best hypothesis no longer raises the occlusion-aware inlier count by Theta.

The estimator takes one :class:`~cuboidcli.fitting.fit_input.FitInput`, a frame's or a room's:
:func:`estimate` runs the sequential loop (:func:`fit_points`), names each cuboid's kind and labels the
points; :func:`fit_depth` and :func:`fit_room` prepare the input first (a depth map and its camera, a
room's points). All take a built solver (:class:`~cuboidcli.solvers.base.CuboidSolver`) and sampler
(:class:`~cuboidcli.sampling.Sampler`) and return ``(cuboids, FitInfo)``; building them by name, with
their weights, is :mod:`cuboidcli.factories`' work.
"""

from __future__ import annotations

import time
from collections.abc import Callable
from dataclasses import dataclass, field, replace

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.align import align_winner
from cuboidcli.fitting.assign import OCCLUDED, assign_points
from cuboidcli.fitting.backend import NumbaBackend, backend_for
from cuboidcli.fitting.box import Scored, StepContext, not_lines, score_params
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.fit_input import FitInput
from cuboidcli.fitting.objects import SceneObject, group_objects
from cuboidcli.fitting.prepare import frame_input, grid_assignment
from cuboidcli.fitting.search import gain_upper_bound, search_step
from cuboidcli.fitting.shell import cuboid_kind
from cuboidcli.fitting.winner import refine_winner
from cuboidcli.geometry import arrays
from cuboidcli.geometry.arrays import device_of, float32, numpy64
from cuboidcli.geometry.backends import resolve_backend
from cuboidcli.geometry.cloud import RoomUp
from cuboidcli.geometry.gravity import Gravity, level_frame
from cuboidcli.geometry.inlier import combine
from cuboidcli.sampling import Sampler, SamplingContext
from cuboidcli.solvers.base import CuboidSolver

#: The fits that vote on a room's object boxes besides the returned one draw 1 / VOTER_SHARE of its
#: hypotheses per step.
VOTER_SHARE = 2

ProgressFn = Callable[[int, int, float], None]
"""progress(step, cuboids_so_far, last_gain) is called after every step."""


@dataclass
class FitInfo:
    """What happened while fitting one frame or room."""

    gains: list[float] = field(default_factory=list)
    """Inlier-count gain of each selected cuboid, in selection order."""
    theta: float = 0.0
    """Stopping threshold used: ``theta`` if given, else k ln n with k = ``theta_log_factor`` (6 by default;
    the paper's 9)."""
    n_points: int = 0
    """Valid fitting points n."""
    iterations: int = 0
    """Sampling steps run, including a final step whose best hypothesis was rejected."""
    batches: list[int] = field(default_factory=list)
    """Batches of |H| hypotheses drawn in each step (adaptive termination draws more when a step's best
    hypothesis misses Theta); 0 for a final step skipped because no hypothesis could gain Theta."""
    stop_reason: str = ""
    """max_cuboids | gain_below_theta | too_few_points."""
    rejected_gain: float | None = None
    """Gain of the best hypothesis of the rejecting step, if any."""
    timing_s: dict = field(default_factory=dict)
    """Per-stage seconds; 'total' is input loaded -> cuboids selected."""
    grid_step: int = 8
    """Step of the fitting grid used (``FitConfig.step_for`` the frame's size)."""
    assignment: np.ndarray | None = None
    """(Hs, Ws) int32 over the fitting grid: k >= 0 inlier of cuboid k, -1 none, -2 occluded, -3 no depth."""
    state: np.ndarray | None = None
    """(N,) f_OAI of the final set at the valid fitting points."""
    gravity: Gravity | None = None
    """The up/down direction used or estimated (None when not needed or not reliable)."""
    align: str = "free"
    """The orientation constraint applied: the configured one, or "free" when no gravity was available."""
    aligned: list[str] = field(default_factory=list)
    """Per selected cuboid: "manhattan", "gravity", "tilted" (a slab kept in its own, tilted plane with its
    edges turned upright) or "free" (an aligned box fitted much worse)."""
    warnings: list[str] = field(default_factory=list)
    """Things the user should know about this fit (one line each)."""
    kind: str = "frame"
    """``frame`` or ``room``: the input's kind."""
    random_generator: str = "torch"
    """Whose generator drew the fit's random numbers: "numpy" (an input fitted on numpy arrays) or "torch"
    (on tensors); the same seed gives other cuboids with the other one."""
    backend_used: str = ""
    """The scoring backend the fit ran on (``config.backend`` resolved: numba, torch, hybrid or room)."""
    labels: np.ndarray | None = None
    """(N,) int32 per fitting point: k >= 0 inlier of cuboid k, -1 none, -2 hidden by or inside a cuboid."""
    fit_points: np.ndarray | None = None
    """(N, 3) float64 the fitting points (a room's voxel means, in scoring order)."""
    room_up: RoomUp | None = None
    """A room's up direction and axes."""
    voxel_m: float | None = None
    """A room: the side of the voxels fitted."""
    visibility: str | None = None
    """A room: the scoring kernels' mode (views, inside, plain)."""
    viewpoint: np.ndarray | None = None
    """A room: (3,) where its shell was seen from."""
    point_labels: np.ndarray | None = None
    """A room: (M,) int32 the label of each input point (that of its voxel's fitting point)."""
    objects: list[SceneObject] = field(default_factory=list)
    """A room's whole objects (furniture with its legs, points no cuboid explains), largest first
    (:func:`cuboidcli.fitting.objects.group_objects`)."""

    def add_depth_time(self, seconds: float) -> None:
        """Count a depth estimation from RGB as part of the frame's fitting time: stage "depth" (first) and
        in "total" (the network is part of the pipeline; loading it is start-up and is not counted)."""
        self.timing_s = {"depth": round(seconds, 6), **self.timing_s}
        self.timing_s["total"] = round(self.timing_s.get("total", 0.0) + seconds, 6)


_COMPILED = False


def warm_up_parts(*parts) -> None:
    """Let each given part (a solver, a sampler) compile its own kernels: ``part.warm_up()``. A part
    without the method, or None, has nothing to compile."""
    for part in parts:
        warm_up = getattr(part, "warm_up", None)
        if warm_up is not None:
            warm_up()


def ensure_compiled(solver: CuboidSolver | None = None, sampler: Sampler | None = None) -> None:
    """Compile (or load from numba's cache) the fused CPU kernels of a fit once per process, outside any
    timing: the numba backend's (scoring, values, refinement) and the given parts' own
    (:func:`warm_up_parts`: the numerical solver's loops, the localised minimal sets of a sampler)."""
    global _COMPILED
    warm_up_parts(solver, sampler)
    if _COMPILED:
        return
    NumbaBackend().warm_up()
    _COMPILED = True


def fit_points(
    prep: FitInput,
    config: FitConfig,
    solver: CuboidSolver,
    sampler: Sampler,
    progress: ProgressFn | None = None,
    timing: dict | None = None,
) -> tuple[list[Cuboid], FitInfo]:
    """Sequential robust fitting on prepared points (Sec. 3.2). ``timing`` collects per-stage seconds;
    ``prep.alignment`` constrains the orientation of the selected cuboids (None = free). The scoring and
    refinement backend is the input's (a room's, which knows how its points were seen), else chosen here,
    once, from ``config.backend`` and the points' device (ValueError for "numba" on a GPU)."""
    config = config.for_kind(prep.kind)
    prep = arrays_for(prep, config, solver, sampler)
    alignment = prep.alignment
    grid = prep.grid
    timing = {} if timing is None else timing
    for k in ("sample", "solve", "score", "update"):
        timing.setdefault(k, 0.0)
    pts = prep.points
    n = pts.shape[0]
    info = FitInfo(
        theta=config.theta_for(n),
        n_points=n,
        grid_step=0 if grid is None else grid.step,
        align="free" if alignment is None else alignment.mode,
        kind=prep.kind,
    )
    sp = score_params(config)
    backend = prep.backend or backend_for(config.backend, device_of(pts))
    info.random_generator = "torch" if arrays.is_tensor(pts) else "numpy"
    info.backend_used = getattr(backend, "name", type(backend).__name__)
    if grid is not None:
        backend.bind_cells(pts, grid.cells)
    gen = arrays.generator(config.seed, pts)  # numpy's for numpy arrays, torch's for tensors
    state = arrays.zeros(n, pts)
    cuboids: list[Cuboid] = []
    if n < config.min_set:
        info.stop_reason = "too_few_points"
        info.state = numpy64(state)
        return cuboids, info
    while True:
        if len(cuboids) >= config.max_cuboids:
            info.stop_reason = "max_cuboids"
            break
        info.iterations += 1
        sampling = SamplingContext(
            pts,
            None if grid is None else grid.index,
            None if grid is None else grid.shape,
            None if grid is None else grid.depth,
            float32(state),
            len(cuboids),
            None if grid is None else grid.focal_cells,
            prep.space,
        )
        if not gain_upper_bound(state) > info.theta:  # no hypothesis can gain Theta: stop without drawing
            info.stop_reason = "gain_below_theta"
            info.rejected_gain = None
            info.batches.append(0)
            break
        gain, best, batches = search_step(
            sampling, sampler, solver, state, sp, config, gen, info.theta, timing, alignment, backend
        )
        info.batches.append(batches)
        t4 = time.perf_counter()
        if not gain > info.theta:
            info.stop_reason = "gain_below_theta"
            info.rejected_gain = gain
            break
        step = StepContext(pts, state, sp, config, backend, gen)
        # the search's gain stands: the backend's scoring loop computed it exactly
        winner = Scored(best, step.values(best), gain)
        if config.refine:
            winner = refine_winner(winner, step)
            t5 = time.perf_counter()
            timing["refine"] = timing.get("refine", 0.0) + t5 - t4
            t4 = t5
        if alignment is not None:
            aligned = align_winner(winner, step, alignment)
            # a box that aligning made a line stays as it was (fitting.box.not_lines)
            winner = aligned if not_lines(aligned.box.half, sp.tau)[0] else replace(winner, kind="free")
            info.aligned.append(winner.kind)
            t5 = time.perf_counter()
            timing["align"] = timing.get("align", 0.0) + t5 - t4
            t4 = t5
        cuboids.append(winner.box.to_cuboid(winner.gain))
        info.gains.append(winner.gain)
        state = combine(winner.values, state)
        timing["update"] += time.perf_counter() - t4
        if progress is not None:
            progress(info.iterations, len(cuboids), winner.gain)
    info.state = numpy64(state)
    return cuboids, info


def estimate(
    inp: FitInput,
    config: FitConfig,
    *,
    solver: CuboidSolver,
    sampler: Sampler,
    progress: ProgressFn | None = None,
) -> tuple[list[Cuboid], FitInfo]:
    """The estimator on a prepared input, a frame's or a room's: the sequential loop (:func:`fit_points`),
    then each cuboid's kind (floor, wall, ceiling, object: :func:`~cuboidcli.fitting.shell.cuboid_kind`
    seen from the input's viewpoint), the label of every fitting point and, for a room, its whole objects.

    Returns the cuboids (in selection order, each with its ``kind`` and ``inlier_gain``) and a FitInfo.
    Deterministic for ``config.seed``.

    A frame's input of numpy arrays is fitted on them when the backend is numba and both parts take numpy
    arrays (``takes_numpy``: the numerical solver, the samplers but the learned one), which needs no torch;
    otherwise on tensors (:meth:`~cuboidcli.fitting.fit_input.FitInput.as_tensors`). The two draw their
    random numbers from different generators (numpy's, torch's), so the same seed gives other cuboids."""
    config = config.for_kind(inp.kind)
    if inp.kind == "room" and getattr(sampler, "name", "") == "learned":
        raise ValueError("the learned sampler weighs the pixels of a depth map; fit a room with sequential")
    inp = arrays_for(inp, config, solver, sampler)
    timing = dict(inp.timing_s)
    cuboids, info = fit_points(inp, config, solver, sampler, progress, timing)
    info.gravity = inp.gravity
    info.warnings = [*inp.warnings, *info.warnings]
    points = numpy64(inp.points)
    name_kinds(cuboids, points, inp)
    room = inp.room
    timing["total"] = time.perf_counter() - inp.started
    t = time.perf_counter()
    backend = inp.backend or backend_for(config.backend, device_of(inp.points))
    labels = assign_points(inp.points, cuboids, score_params(config), backend)
    if room is None:
        if info.state is not None and len(cuboids):
            labels[info.state < 0] = OCCLUDED
        info.assignment = grid_assignment(inp, labels)
    timing["assign"] = time.perf_counter() - t
    info.labels = labels
    if room is not None:
        in_order = np.empty_like(labels)
        in_order[room.order] = labels
        info.point_labels = in_order[room.inverse]
        t = time.perf_counter()
        info.objects = group_objects(points, labels, cuboids, room.up.up, room.voxel_m, room.colors)
        timing["objects"] = time.perf_counter() - t
        if config.object_fits > 1:  # more fits vote on the object boxes (fitting/consensus.py)
            t = time.perf_counter()
            votes = (inp, config, points, info.objects)
            info.objects = _agreed(*votes, solver, sampler, progress, info.iterations)
            timing["object_fits"] = time.perf_counter() - t
            timing["total"] += timing["object_fits"]
        info.fit_points, info.room_up, info.voxel_m = points, room.up, room.voxel_m
        info.visibility, info.viewpoint = room.visibility, inp.viewpoint
    info.timing_s = {k: round(v, 6) for k, v in timing.items()}
    return cuboids, info


def name_kinds(cuboids: list[Cuboid], points: np.ndarray, inp: FitInput) -> None:
    """Name each cuboid's kind in place (:func:`~cuboidcli.fitting.shell.cuboid_kind`), then, for a room,
    apply the room's shell rules (:mod:`cuboidcli.fitting.room`)."""
    for c in cuboids:
        c.kind = cuboid_kind(points, c, inp.down, inp.viewpoint)
    room = inp.room
    if room is not None:
        from cuboidcli.fitting import room as room_rules

        room_rules.low_walls_are_furniture(cuboids, points, room.up.up)
        seen = room_rules.BEYOND_SHARE if inp.views == "none" else room_rules.BEYOND_SHARE_SEEN
        room_rules.beyond_the_room_is_wall(cuboids, points, room.up.up, seen)
        room_rules.open_behind_is_wall(cuboids, points, room.up.up, inp.viewpoint)
        room_rules.low_slabs_are_floor(cuboids, room.up.up)


def _agreed(inp, config, points, first, solver, sampler, progress, steps) -> list[SceneObject]:
    """The object boxes that a majority of ``config.object_fits`` fits of a room agree on: the first fit's
    objects ``first`` and those of more fits with seeds drawn from ``config.seed``
    (:func:`~cuboidcli.fitting.consensus.agreed_objects`). Their steps go on from ``steps`` in
    ``progress``."""
    from cuboidcli.fitting.consensus import agreed_objects

    room = inp.room
    backend = inp.backend or backend_for(config.backend, device_of(inp.points))
    fits = [first]
    for k in range(1, config.object_fits):
        seed = int(np.random.SeedSequence([config.seed, k]).generate_state(1)[0])
        # half the hypotheses: the object boxes of such fits are as good, in half the time (docs/scenes.md)
        other = replace(config, seed=seed, hypotheses=max(1, config.hypotheses // VOTER_SHARE))
        shifted = None if progress is None else (lambda it, n, gain, s=steps: progress(s + it, n, gain))
        cuboids, info = fit_points(inp, other, solver, sampler, shifted, {})
        steps += info.iterations
        name_kinds(cuboids, points, inp)
        labels = assign_points(inp.points, cuboids, score_params(other), backend)
        fits.append(group_objects(points, labels, cuboids, room.up.up, room.voxel_m, room.colors))
    return agreed_objects(fits, level_frame(room.up.up), config.object_fits // 2 + 1)


def arrays_for(inp: FitInput, config: FitConfig, solver, sampler) -> FitInput:
    """``inp`` as the arrays it is fitted on: an input of numpy arrays stays so where both parts take numpy
    arrays (``takes_numpy``) and the backend is numba (a frame) or the input's own (a room's, whose kernels
    are numba loops), and becomes tensors otherwise."""
    if arrays.is_tensor(inp.points):
        return inp
    numba = inp.backend is not None or resolve_backend(config.backend, "cpu") == "numba"
    if numba and all(getattr(part, "takes_numpy", False) for part in (solver, sampler)):
        return inp
    return inp.as_tensors()


def fit_depth(
    depth_m: np.ndarray,
    camera: Camera,
    config: FitConfig | None = None,
    *,
    solver: CuboidSolver,
    sampler: Sampler,
    progress: ProgressFn | None = None,
) -> tuple[list[Cuboid], FitInfo]:
    """Fit cuboids to a depth map (H, W) in metres (0/NaN/inf = missing) seen by ``camera``, with a built
    ``solver`` and ``sampler`` (:mod:`cuboidcli.factories` builds them by name; :class:`cuboidcli.api.Fitter`
    does both): :func:`~cuboidcli.fitting.prepare.frame_input`, then :func:`estimate`."""
    config = (config or FitConfig()).for_kind("frame")
    if config.device == "cpu":
        ensure_compiled(solver, sampler)
    inp = frame_input(depth_m, camera, config)
    return estimate(inp, config, solver=solver, sampler=sampler, progress=progress)


def fit_room(
    points: np.ndarray,
    config: FitConfig | None = None,
    *,
    solver: CuboidSolver,
    sampler: Sampler,
    viewpoints: np.ndarray | None = None,
    up_hint: np.ndarray | None = None,
    progress: ProgressFn | None = None,
) -> tuple[list[Cuboid], FitInfo]:
    """Fit a room given as points (N, 3), metres, in its own world frame (``viewpoints`` (N, 3): the camera
    that saw each point, None for a bare cloud; ``up_hint`` (3,): the direction the input calls up):
    :func:`~cuboidcli.fitting.room.room_input`, then :func:`estimate`."""
    from cuboidcli.fitting.room import room_input

    config = (config or FitConfig()).for_kind("room")
    warm_up_room(solver, sampler)
    inp = room_input(points, config, viewpoints, up_hint)
    return estimate(inp, config, solver=solver, sampler=sampler, progress=progress)


def warm_up_room(solver: CuboidSolver | None = None, sampler: Sampler | None = None) -> None:
    """Compile the room's scoring kernels and the given parts' own, once per process, outside any timing."""
    from cuboidcli.fitting.room_backend import warm_up_room as warm_up_kernels

    warm_up_kernels()
    warm_up_parts(solver, sampler)

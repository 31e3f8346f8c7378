"""Settings of the estimator, with the paper's symbols and units. Defaults are the paper's NYU values.

Each field's docstring is its documentation everywhere: the first paragraph is also the help text of the
command-line option that sets the field (``cuboids fit --help``, cuboidcli/cli/options.py), and the field's
default is the option's (README.md's option table too: ``python scripts/readme_options.py`` rewrites it);
later paragraphs give the details.
"""

from __future__ import annotations

import math
from dataclasses import asdict, dataclass, fields, replace

from cuboidcli.fitting.checks import Check, choice, number, switch, text, vector, whole
from cuboidcli.fitting.parts import SAMPLERS, SOLVERS
from cuboidcli.geometry.backends import BACKENDS

#: Orientation constraints of selected cuboids (FitConfig.align).
ALIGN_MODES = ("free", "gravity", "manhattan")
#: How a room's points count against a cuboid (FitConfig.visibility): auto, and the room kernels' modes.
#: (The kernels' own list, geometry.room.VISIBILITY, loads numba: not imported for a constant.)
VISIBILITY_CHOICES = ("auto", "views", "inside", "plain")
#: The settings whose default depends on the input: a frame (a depth map or a photo) or a room (a scan,
#: a sequence, a point array). A setting left at None takes its input's value (:meth:`FitConfig.for_kind`).
KIND_DEFAULTS: dict[str, dict[str, int]] = {
    "frame": {"max_cuboids": 8, "fit_points": 4800},
    "room": {"max_cuboids": 60, "fit_points": 40000},
}
#: Settings only a room reads; a frame's result leaves them out (:meth:`FitConfig.to_dict`).
ROOM_ONLY = ("voxel_m", "visibility", "up", "virtual_view_m", "object_fits")


@dataclass(frozen=True)
class FitConfig:
    hypotheses: int = 3072
    """|H|: cuboid hypotheses sampled per step (the paper: 4096, as ``cuboids evaluate --preset paper``).

    The paper tests with 4096 (the ``paper`` preset and the baselines use it); with localised minimal sets
    3072 find the same cuboids (AUC@20 within 0.5 points on real and synthetic frames) in two thirds of the
    time, so it is the default here. 32 in training."""
    max_cuboids: int | None = None
    """Upper bound on |M|, the number of cuboids returned.

    None = the input's default: 8 for a frame, 60 for a room (:data:`KIND_DEFAULTS`; on real scans and
    sequences Theta ends a room first, at 15-55 cuboids)."""
    min_set: int = 6
    """C: points per minimal set, drawn with replacement (Sec. 3.3)."""
    tau_sq_m2: float = 0.004
    """tau: inlier threshold on the SQUARED distance, m^2 (0.004 m^2 ~ 6.3 cm); 0.04 outdoors."""
    beta: float = 5.0
    """beta: softness of the sigmoid inlier function f_I."""
    tau_c_sq_m2: float | None = None
    """tau_c: where the occlusion penalty f_O turns linear, m^2; None = 2 * tau (the paper's test value)."""
    theta: float | None = None
    """Theta: minimum inlier-count gain for a cuboid to be added; by default k ln n (n fitting points,
    k = ``theta_log_factor``; the paper's k is 9, as ``cuboids evaluate --preset paper``).

    None = ``theta_log_factor`` * ln n."""
    theta_log_factor: float = 6.0
    """k in the default Theta = k ln n (n = fitting points); the paper's k is 9."""
    grid_step: int | None = None
    """Fit on every n-th pixel of the depth map in each direction; by default the step that gives about
    ``fit_points`` points for the frame's size (8 at 640x480: 60x80 = 4800, the paper's grid; 51 for a
    12 MP photo).

    None = from the frame's size (``step_for``): the smallest step whose grid has at most
    ``fit_points`` cells, so the fitting time does not grow with the resolution of the input."""
    fit_points: int | None = None
    """At most this many fitting points: a frame's automatic ``grid_step`` gives about this many (the
    paper's 60x80 grid, 4800), a room's voxels grow until no more remain (40,000).

    None = the input's default (:data:`KIND_DEFAULTS`)."""
    occlusion_aware: bool = True
    """Score with the occlusion-aware inlier count (OAI); off = plain inlier counting (the paper's no-OAI
    baselines)."""
    sampler: str = "sequential"
    """Sampling weights of the points of minimal sets (of a localised set's first point)

    One of the samplers registered in :data:`cuboidcli.fitting.parts.PARTS`; the command line's help lists
    them with their one-line help (:func:`cuboidcli.fitting.parts.describe`)."""
    local_fraction: float = 0.75
    """Share of minimal sets drawn from a 3D ball (radii ``local_radii_m``) around their first point; 0 = the
    paper's global sets.

    Of each batch's hypotheses, this share has a localised minimal set: the first point from the sampling
    weights, the other C - 1 from a 3D ball around it (sampling/proposals.py). The rest are global sets
    (all C points from the sampling weights, the paper's)."""
    local_radii_m: tuple[float, ...] = (0.15, 0.3, 0.6, 1.2)
    """Radii (m) of the balls of localised sets, one drawn per hypothesis."""
    max_batches: int = 4
    """Adaptive termination: at most this many batches of |H| hypotheses per step before concluding that
    nothing gains Theta; 1 = the paper (one batch, then stop).

    When the best hypothesis of a step does not gain Theta, further batches of |H| hypotheses are drawn, up
    to this many per step, until a structure that would gain Theta would have been drawn with probability
    ``confidence``."""
    confidence: float = 0.99
    """Adaptive termination: the probability of having drawn a structure that gains Theta."""
    local_success: float = 0.05
    """Adaptive termination: assumed probability that a localised set seeded on a structure yields a
    hypothesis that wins it (a conservative figure; global sets count as never winning a small one)."""
    solver: str = "numerical"
    """The solver that turns a minimal set into a cuboid

    One of the solvers registered in :data:`cuboidcli.fitting.parts.PARTS`; the command line's help lists
    them with their one-line help (:func:`cuboidcli.fitting.parts.describe`)."""
    a_min: float = 1e-3
    """a_min: smallest cuboid half-size, m."""
    a_max: float = 2.0
    """a_max: largest cuboid half-size, m."""
    slab_max_m: float | None = 4.0
    """Largest half-length (m) of a wall or floor slab along its long axes when the winner grows (other
    boxes: ``a_max``).

    A slab is a box whose thinnest axis is under a quarter of its middle one; its two long axes may grow to
    this bound, so that a wall or a floor may be 8 m long while its thickness stays bounded, instead of
    being split into patches (real frames: coverage 69.6 -> 73.8 %, AUC@20 65.7 -> 67.0 %; synthetic test
    split: AUC@20 92.0 -> 92.4 %). None = a_max (the paper's bound)."""
    align: str = "manhattan"
    """Orientation of the selected cuboids: ``manhattan`` (walls, floor and ceiling on the room's axes, other
    boxes on them or upright with a free yaw), ``gravity`` (upright boxes, free yaw), ``free`` (any
    rotation, the paper). gravity and manhattan need the down direction: ``gravity_down`` or one estimated
    from the depth map (else the fit stays free).

    manhattan is the default: real frames AUC@20 71.9 % against 72.4 % free with 92 % of the walls, floor
    and ceiling within 3 degrees of the room's axes (free: 8 %), synthetic test split 93.7 % against 93.5 %
    (98 % against 23 %)."""
    upright_fraction: float = 0.5
    """With ``align`` gravity or manhattan: the share of each batch's minimal sets solved as upright,
    yaw-only boxes; the rest are free.

    With manhattan half of the upright ones keep the room's axes (no rotation at all)."""
    upright_set_size: int = 6
    """Points of a minimal set that an upright box is solved from (its first ones; free boxes use all
    ``min_set``). A yaw-only box has seven parameters instead of nine, and one on the room's axes six, but
    fewer points did not pay: with 4, real frames AUC@20 72.7 % / AUC@5 45.0 % against 71.9 / 45.7 % with
    6, the synthetic test split 93.6 / 80.3 % against 93.7 / 80.2 %, no faster per frame, and with every
    hypothesis upright the synthetic AUC@5 fell from 80.7 to 78.0 %: four points leave a box too loose."""
    gravity_down: tuple[float, float, float] | None = None
    """Down direction in camera coordinates from a sensor (an IMU, ARKit); by default it is estimated from
    the depth map where ``align`` needs it.

    None = estimate it."""
    solver_lr: float = 0.01
    """Learning rate of the numerical solver's Adam (0.01 NYU, 0.5 outdoors)."""
    solver_iters: int = 50
    """Adam iterations of the numerical solver."""
    refine_iters: int = 25
    """Adam iterations of the refinement of each selected cuboid (``refine``)."""
    refine_lr: float = 0.003
    """Learning rate of the refinement's Adam (m, and radians of the axis-angle, per step)."""
    refine_keep: float = 0.005
    """The refined cuboid replaces the selected one unless its inlier-count gain drops by more than this
    share of the selected one's (0.005 = 0.5 %); a negative share keeps the selected one always."""
    prescore_points: int = 0
    """Fast path: if > 0, score all hypotheses on this many random points first and rescore only the
    best ``rescore_top`` on all points. 0 = exact scoring of every hypothesis on every point."""
    rescore_top: int = 64
    """Hypotheses rescored on all points when the fast path is on."""
    refine: bool = True
    """Refine each selected cuboid on its inliers and grow it (``grow_rounds``); off = the paper's plain
    estimator.

    Refinement minimises the inliers' occlusion-aware distance and keeps the refined box only if its
    inlier-count gain does not drop (fitting/winner.py refine_winner, fitting/refine.py)."""
    grow_rounds: int = 8
    """After refinement, up to this many rounds push the winner's faces outwards while its inlier-count
    gain rises (fitting/winner.py grow_cuboid): a minimal set of six points spans only part of a wall or
    a table. 0 = no growing."""
    grow_thickness: bool = True
    """Growing may also thicken a slab (a seat top grows down into the seat's front)."""
    grow_step_m: float = 0.1
    """Smallest step a face is pushed by when growing, m (also the resolution at which a box ends)."""
    refine_max_points: int = 1024
    """At most this many inliers (a fixed random subset) enter the refinement."""
    seed: int = 0
    """Seed of the sampler's random generator; the same seed gives the same cuboids."""
    device: str = "cpu"
    """cpu or cuda."""
    voxel_m: float = 0.035
    """A room: side of the voxels whose mean points are fitted (m); grown where needed so that at most
    ``fit_points`` points remain.

    On synthetic room scans (3 rooms, 8 views each) 3.5 cm voxels and up to 40,000 points recall twice
    the furniture boxes of 5 cm and 20,000 (IoU >= 0.25: 28.6 against 14.3 %; AUC@5 88.1 against 84.4 %)
    in twice the time (9.3 against 4.3 s a room); 3 cm and 50,000 add little (32.1 %, 14.9 s)."""
    visibility: str = "auto"
    """A room: how points count against a cuboid: ``views`` (no cuboid hides a point from its camera; a bare
    cloud is seen from just outside its surfaces), ``inside``, ``plain``; auto = views.

    ``views``: a cuboid must not hide a point from the camera that saw it; ``inside``: observed surface
    points must not lie inside a solid box; ``plain``: no penalty."""
    up: tuple[float, float, float] | None = None
    """A room: its up direction in the input's frame, a unit vector; None = estimated (the Manhattan axis
    nearest the input's own up: the cameras' mean up, y for glTF, else z)."""
    virtual_view_m: float = 0.5
    """A bare cloud's points are taken as seen from this far out of their surface, on the side rays cross
    empty space (else towards the inside of the room) (m)."""
    object_fits: int = 5
    """A room: fits whose object boxes vote; a box a majority of them find is kept (1 = one fit's boxes).

    The cuboids are the first fit's; the others cost a fit each (fitting/consensus.py)."""
    backend: str = "auto"
    """Kernels that score hypotheses and refine winners: ``auto`` (numba on the CPU, torch on a GPU),
    ``numba`` (the fused CPU loops; refused on a GPU) or ``torch`` (the reference kernels, any device).

    Both compute the same values in float64 and select the same cuboids for a seed up to rounding; numba
    is the faster on the CPU (it prunes hypotheses that cannot win and builds no (H, N, 6) tensors)."""

    @property
    def tau_c(self) -> float:
        return 2.0 * self.tau_sq_m2 if self.tau_c_sq_m2 is None else self.tau_c_sq_m2

    def theta_for(self, n_points: int) -> float:
        return self.theta_log_factor * math.log(max(n_points, 2)) if self.theta is None else self.theta

    def for_kind(self, kind: str) -> FitConfig:
        """These settings for an input of ``kind`` ("frame" or "room"): the settings left at None that have
        a default per kind (:data:`KIND_DEFAULTS`) take it. Idempotent."""
        unset = {k: v for k, v in KIND_DEFAULTS[kind].items() if getattr(self, k) is None}
        return replace(self, **unset) if unset else self

    def to_dict(self, kind: str | None = None) -> dict:
        """The settings as a dict; for ``kind`` "frame" without the settings only a room reads
        (:data:`ROOM_ONLY`), which a frame's result does not record."""
        d = asdict(self)
        if kind == "frame":
            for name in ROOM_ONLY:
                d.pop(name)
        return d

    def step_for(self, height: int, width: int) -> int:
        """The fitting grid's step for an (height, width) frame: ``grid_step`` when set, else the smallest
        step whose grid (ceil(H / s) x ceil(W / s) cells) has at most ``fit_points`` cells."""
        if self.grid_step is not None:
            return self.grid_step
        n = self.for_kind("frame").fit_points
        step = max(1, math.ceil(math.sqrt(height * width / n) - 1e-9))
        while step > 1 and math.ceil(height / (step - 1)) * math.ceil(width / (step - 1)) <= n:
            step -= 1
        while math.ceil(height / step) * math.ceil(width / step) > n:
            step += 1
        return step

    def __post_init__(self) -> None:
        self.check(parts=False)

    def check(self, parts: bool = True) -> None:
        """Raise a one-line ValueError for the first setting that is out of range (:data:`CHECKS`, in field
        order), or a backend the device cannot run. ``parts``: also that ``sampler`` and ``solver`` name
        registered parts (:mod:`cuboidcli.fitting.parts`), as the API and the command line require, which
        build them by name; a FitConfig is made without it (``fit_depth`` takes parts built elsewhere,
        whatever their names), so a construction or :func:`dataclasses.replace` checks the ranges only."""
        for f in fields(self):
            if parts or f.name not in ("sampler", "solver"):
                error = setting_error(f.name, getattr(self, f.name))
                if error is not None:
                    raise ValueError(error)
        if self.a_min > self.a_max:
            raise ValueError(f"a_min ({self.a_min}) must not exceed a_max ({self.a_max})")
        if self.backend == "numba" and not self.device.startswith("cpu"):
            raise ValueError(
                f"backend 'numba' runs on the CPU only, not on {self.device!r}; use auto or torch"
            )


def _unit_vector(v) -> bool:
    return len(v) == 3 and all(map(math.isfinite, v)) and abs(math.hypot(*v) - 1.0) < 1e-6


def _direction(v) -> bool:
    return len(v) == 3 and all(map(math.isfinite, v)) and math.hypot(*v) > 0


#: Largest count of hypotheses, cuboids, points or iterations: far beyond any useful setting, small enough
#: that a typo (an extra few zeros) is refused rather than run out of memory.
_MANY = 1_000_000
_METRES = number(0, 1000, open_low=True, unit="m")
_SQ_METRES = number(0, 1000, open_low=True, unit="m^2")
_FRACTION = number(0, 1)
_LR = number(0, 100, open_low=True)
_CHOOSE_LISTED = "{name} {value}: choose {listed}"

#: The check of every setting, the only one of that setting (:meth:`FitConfig.check` adds the checks
#: across settings). Messages are one line; the command line prints them with the flag as the name.
CHECKS: dict[str, Check] = {
    "hypotheses": whole(1, 100_000),
    "max_cuboids": whole(1, 1000),
    "min_set": whole(1, 1000),
    "tau_sq_m2": _SQ_METRES,
    "beta": number(0, 1e6, open_low=True),
    "tau_c_sq_m2": _SQ_METRES,
    "theta": number(),
    "theta_log_factor": number(0, 1e6),
    "grid_step": whole(1, 10_000),
    "fit_points": whole(1, 10 * _MANY),
    "occlusion_aware": switch(),
    "sampler": choice(SAMPLERS),
    "local_fraction": _FRACTION,
    "local_radii_m": vector(
        "radii, each a number > 0 and <= 1000 m",
        lambda v: len(v) > 0 and all(_METRES.allows(r) and r is not None for r in v),
    ),
    "max_batches": whole(1, 1000),
    "confidence": number(0, 1, open_low=True, open_high=True),
    "local_success": number(0, 1, open_low=True),
    "solver": choice(SOLVERS),
    "a_min": _METRES,
    "a_max": _METRES,
    "slab_max_m": _METRES,
    "align": choice(ALIGN_MODES, _CHOOSE_LISTED),
    "upright_fraction": _FRACTION,
    "upright_set_size": whole(1, 1000),
    "gravity_down": vector("3 finite numbers, not all 0", _direction),
    "solver_lr": _LR,
    "solver_iters": whole(0, _MANY),
    "refine_iters": whole(1, _MANY),
    "refine_lr": _LR,
    "refine_keep": number(-1, 1),
    "prescore_points": whole(0, 10 * _MANY),
    "rescore_top": whole(1, _MANY),
    "refine": switch(),
    "grow_rounds": whole(0, 1000),
    "grow_thickness": switch(),
    "grow_step_m": _METRES,
    "refine_max_points": whole(1, 10 * _MANY),
    "seed": whole(0, 2**63 - 1),
    "device": text("cpu, cuda or cuda:N", lambda v: v.split(":")[0] in ("cpu", "cuda")),
    "voxel_m": _METRES,
    "visibility": choice(VISIBILITY_CHOICES, _CHOOSE_LISTED),
    "up": vector("a unit vector of 3 finite numbers", _unit_vector),
    "virtual_view_m": _METRES,
    "object_fits": whole(1, 99),
    "backend": choice(BACKENDS, "{name} must be one of {listed}, got {value}"),
}


def setting_error(name: str, value, flag: str | None = None, choices: tuple[str, ...] | None = None):
    """The one-line message when ``value`` is not allowed for field ``name`` (:data:`CHECKS`), naming it
    ``flag`` when given (``--max-cuboids``); None when it is allowed. ``choices``: as :meth:`Check.error`."""
    check = CHECKS.get(name)
    return None if check is None else check.error(flag or name, value, choices)


def resolve_device(device: str, name: str = "device") -> str:
    """The torch device ``device`` means: ``auto`` is cuda if there is one, else cpu; cuda without one, or
    any other name, is a one-line ValueError naming the setting ``name`` (``--device`` on the command
    line). What :attr:`FitConfig.device` holds, and every command's ``--device``.

    ``auto`` on a machine without a GPU driver is cpu without asking torch: a frame fitted on the CPU
    never imports it."""
    if device == "auto" and not _may_have_gpu():
        return "cpu"
    if device not in ("auto", "cpu", "cuda"):
        raise ValueError(f"{name} {device!r}: choose auto, cpu or cuda")
    if device == "cpu":
        return device
    import torch

    if device == "auto":
        return "cuda" if torch.cuda.is_available() else "cpu"
    if not torch.cuda.is_available():
        raise ValueError(f"{name} cuda: no CUDA device is available; use {name} cpu or auto")
    return device


def _may_have_gpu() -> bool:
    """Whether torch might find a GPU here: an NVIDIA driver that reports a device (asked through NVML,
    which leaves CUDA uninitialised, so forked workers can still use it) or a ROCm device node. False
    means surely none; True is settled by torch."""
    import ctypes
    import os

    if os.path.exists("/dev/kfd"):
        return True
    for lib in ("libnvidia-ml.so.1", "nvml.dll"):
        try:
            nvml = ctypes.CDLL(lib)
        except OSError:
            continue
        count = ctypes.c_uint(0)
        try:
            if nvml.nvmlInit_v2() != 0:
                return False
            ok = nvml.nvmlDeviceGetCount_v2(ctypes.byref(count)) == 0
            nvml.nvmlShutdown()
        except AttributeError:  # an NVML without these entry points: let torch decide
            return True
        return ok and count.value > 0
    return False


#: Outdoor settings of the paper's SMH experiments.
OUTDOOR = dict(tau_sq_m2=0.04, a_min=2.0, a_max=30.0, solver_lr=0.5)

"""End-to-end fine-tuning of the learned components (paper Sec. 3.5 and Sec. 4, "End-to-end network
fine-tuning"): sampler + neural solver on depth input, or depth network + sampler (+ neural solver) on RGB.

One scene runs |M| instances in sequence, as the sampler's own training does
(:mod:`cuboidcli.learn.sampler_train`), but now every component between the image and the task loss
carries gradients:

- features Y: the true fitting points (depth input) or the back-projected grid of the depth network's
  prediction (RGB input; differentiable in the network's weights v);
- sampling: Q maps and selection weights from the sampling-weight network on (Y's depth, state), drawn
  K times into sets of |H| minimal sets (policy-gradient term for w and, through the net's input, for v);
- solving: the neural solver (differentiable in its weights and its input points) or the numerical
  solver with implicit-function gradients w.r.t. the points (:mod:`cuboidcli.solvers.implicit`);
- selection: p(h | H) = softmax(alpha I_i(Y, M, h)) with the inlier gains on Y, as inference selects;
- task loss: l(h) = -I_c(Z, M u {h}) / N on the TRUE points Z. With depth input Z = Y. With RGB input the
  paper's training "relies on ground-truth depth"; measuring the loss on Y instead would let the depth
  network flatten the scene into something easy to fit.

The loss of an instance is (1/K) sum_k [ clamp(E_k - mean E) log p(H_k) + E_k ], E_k = E_{h ~ p(h|H_k)}[l]
with l clamped to at most ``loss_clamp`` (the paper's "clamp losses to an absolute maximum of 0.3"):
the gradient estimate of the paper's Eq. 10, with the mean of the K expectations as baseline. Following
the paper's fine-tuning column (appendix Table 7) alpha is 1000 and the regularisers are off by default.
The states of Y and of Z are updated with the hypothesis of the best gain on Y between instances.

Validation after every epoch fits the val frames with the current networks (from RGB through the depth
network when ``rgb``), scores them against the TRUE depth with the paper's metrics and keeps the weights
of the best AUC@20 cm. Files in ``out_dir``: ``config.json``, ``log.jsonl``, ``last.pt`` (training state,
``resume`` continues from it), and the best weights under the names ``cuboids fit --weights DIR`` reads:
``sampler_v2.pt``, ``solver_v2.pt`` (neural solver) and ``depth_v2.pt`` (RGB). The module prints nothing.

Multi-process (``torchrun``, see :mod:`cuboidcli.learn.distributed`), as the sampler's own training does
it (:mod:`cuboidcli.learn.sampler_train`): every rank holds replicas of the networks and loads every
training scene. The B scenes of a step are split over the W ranks, rank r taking the step's scenes r,
r + W, ... (a rank may get none, e.g. in a last partial batch), so ``batch`` stays the global number of
scenes per step and an epoch has as many steps as in one process; use a ``batch`` that is a multiple of W
to keep every rank busy. Each rank scales its scene losses by 1 / B of the global batch and the gradients
are summed over the ranks by one all-reduce per step before the Adam step
(:meth:`~cuboidcli.learn.distributed.DistContext.sum_gradients`; a fixed network, lr 0, has no gradients
and takes no part), so every rank steps with the mean gradient of the global batch and the replicas stay
bit-identical (the depth network's batch norm runs in eval mode, so no statistics drift apart). Rank r
draws its hypotheses from its own generator (:func:`~cuboidcli.learn.sampler_train.draw_seed`; rank 0
keeps the single-process stream), so a run is reproducible for a given seed and number of processes but
differs from a single-process run. The step records of all ranks are gathered, so the log covers the
whole batch. The val frames are split over the ranks the same way and their per-frame metrics gathered
in frame order and aggregated on every rank, so the validation numbers equal a single process's (fitting
is seeded per frame) and every rank takes the same best-weights decision. Rank 0 alone writes files and
calls ``on_event``; the ``max_minutes`` decision is taken on its clock and broadcast, so all ranks stop
after the same epoch. ``last.pt`` holds every rank's draw generator state (``draw_rngs``) and the
``world_size``: resuming with the same number of processes continues the run exactly; with another
number, the ranks the checkpoint has a state for restore it and the others start a fresh stream (a valid
continuation, not the uninterrupted run). The ``end`` record then adds ``world_size`` and
``param_sha256``, one hash of all the networks' final weights per rank, all equal when in sync.
"""

from __future__ import annotations

import math
import time
from collections.abc import Callable
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F  # noqa: N812 - the usual alias
from torch import Tensor

from cuboidcli.camera import Camera
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import fit_depth, prepare_points
from cuboidcli.geometry.kernels import combine, oai_per_cuboid
from cuboidcli.io.checkpoints import load_net
from cuboidcli.io.dataset import Frame
from cuboidcli.learn.distributed import DistContext
from cuboidcli.learn.sampler_data import dataset_splits, epoch_order
from cuboidcli.learn.sampler_loss import (
    correlation_loss,
    entropy_loss,
    inlier_masking_loss,
    set_log_prob,
)
from cuboidcli.learn.sampler_train import SamplerSchedule, draw_generator, draw_states
from cuboidcli.learn.trainer import (
    Run,
    RunConfig,
    StepResult,
    TrainingJob,
    Validation,
    batched,
    resumed,
    run_job,
    shared_batch_step,
)
from cuboidcli.nets.checkpoint import checkpoint_dict
from cuboidcli.nets.sampler import SamplerNet
from cuboidcli.nets.sampler import net_from_checkpoint as sampler_from_checkpoint
from cuboidcli.sampling import draw_sets_and_maps
from cuboidcli.sampling.learned import LearnedSampler
from cuboidcli.weights import FILES, default_path, resolve

STATE_KIND = "finetune-state"
#: The files it writes, in the layout ``--weights DIR`` reads.
SAMPLER_NAME, SOLVER_NAME, DEPTH_NAME = FILES["sampler"], FILES["solver"], FILES["depth"]
SOLVERS = ("neural", "numerical")


@dataclass(frozen=True)
class FinetuneConfig(SamplerSchedule):
    """Schedule of a fine-tuning run; defaults follow the paper's fine-tuning column except the rates. The
    fields it shares with sampler training are :class:`~cuboidcli.learn.sampler_train.SamplerSchedule`'s,
    with the defaults redeclared here."""

    rgb: bool = False
    """Fine-tune from RGB: the depth network's prediction is the input (needs RGB frames)."""
    solver: str = "neural"
    """neural (fine-tuned too) | numerical (implicit-function gradients; not trained)."""
    epochs: int = 10
    """Epochs."""
    lr: float = 1e-5
    """Adam learning rate of the sampling-weight network (the paper: 1e-7 for 25 GPU epochs); 0 keeps a
    network fixed (also for solver_lr and depth_lr)."""
    solver_lr: float | None = None
    """Of the neural solver; None = lr."""
    depth_lr: float | None = None
    """Of the depth network; None = lr."""
    alpha: float = 1000.0
    grad_top: int = 4
    """The differentiable expectation E_h[l] runs over the hypotheses of the grad_top largest gains of a
    set (softmax renormalised over them); with alpha = 1000 the rest carry a negligible selection weight,
    and the occlusion-aware count with gradients is the most expensive part of a step."""
    kappa_corr: float = 0.0
    kappa_entropy: float = 0.0
    kappa_im: float = 0.0
    val_hypotheses: int = 512

    def __post_init__(self) -> None:
        if self.solver not in SOLVERS:
            raise ValueError(f"solver must be one of {SOLVERS}, got {self.solver!r}")
        if self.solver == "numerical" and not self.rgb:
            raise ValueError(
                "fine-tuning with the numerical solver on depth input trains only the sampler: use "
                "'cuboids train sampler', or --solver neural, or --rgb"
            )
        if self.device != "cpu":
            raise ValueError(f"fine-tuning runs on the CPU in this version (got device {self.device!r})")
        super().__post_init__()
        for name in ("val_hypotheses", "grad_top"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")
        for name in ("lr", "solver_lr", "depth_lr"):
            value = getattr(self, name)
            if value is not None and not value >= 0:
                raise ValueError(f"{name} must be positive (or 0: keep the network fixed), got {value}")


@dataclass
class Scene:
    """A training frame: true fitting points Z, the grid, and (RGB) the image and pixel coordinates."""

    name: str
    camera: Camera
    z_points: Tensor  # (N, 3) float64, m
    grid_index: Tensor  # (N,) long
    grid_shape: tuple[int, int]
    depth_grid: Tensor  # (Hs, Ws) float32, true depth on the grid (0 = invalid)
    grid_step: int
    rgb: Tensor | None = None  # (1, 3, h, w) float32 in [0, 1] at the depth net's input size
    uv: Tensor | None = None  # (N, 2) float64 pixel coordinates of the fitting points


def load_scene(frame: Frame, grid_step: int, rgb_size: tuple[int, int] | None) -> Scene | None:
    """Read a frame; None when it has fewer than 6 valid points (or no RGB when ``rgb_size``)."""
    depth = frame.depth_m()
    prep = prepare_points(depth, frame.camera, grid_step)
    if prep.points.shape[0] < 6:
        return None
    scene = Scene(
        frame.name,
        frame.camera,
        prep.points.double(),
        prep.grid_index,
        prep.grid_shape,
        prep.depth_grid.float(),
        grid_step,
    )
    if rgb_size is not None:
        from cuboidcli.depth.estimator import resize

        image = frame.rgb()
        if image is None:
            return None
        small = resize(image, *rgb_size)
        scene.rgb = torch.from_numpy(np.ascontiguousarray(small)).permute(2, 0, 1)[None].float() / 255.0
        u, v = frame.camera.pixel_grid(grid_step)
        uv = np.stack([u.reshape(-1), v.reshape(-1)], 1)[prep.grid_index.numpy()]
        scene.uv = torch.from_numpy(uv)
    return scene


def _has_rgb(frame) -> bool:
    """Whether a frame has a colour image (dataset folders: an rgb file; NYU's .mat: always)."""
    return getattr(frame, "rgb_path", True) is not None


def predicted_grid(depth_net, scene: Scene) -> Tensor:
    """The depth network's metric prediction on the fitting grid (Hs, Ws), differentiable in its weights.

    As :class:`~cuboidcli.depth.estimator.BuiltinDepthEstimator`: predict at the net's input size, scale by
    f / f_canonical, resize to the image (bilinear) and take every grid_step-th pixel.
    """
    from cuboidcli.depth.estimator import focal_factor

    cam = scene.camera
    factor = focal_factor(depth_net.config, cam)
    depth_net.eval()  # batch-norm statistics stay frozen: fine-tuning sees one image at a time
    pred = depth_net(depth_net.normalise(scene.rgb)) * factor  # (1, 1, h, w)
    if pred.shape[-2:] != (cam.height, cam.width):
        pred = F.interpolate(pred, size=(cam.height, cam.width), mode="bilinear", align_corners=False)
    return pred[0, 0, :: scene.grid_step, :: scene.grid_step]


def backproject_grid(grid: Tensor, scene: Scene) -> Tensor:
    """Fitting points Y (N, 3) float64 from a depth grid (Hs, Ws) at the scene's valid cells."""
    cam = scene.camera
    z = grid.reshape(-1)[scene.grid_index].double()
    u, v = scene.uv[:, 0], scene.uv[:, 1]
    return torch.stack([(u - cam.cx) / cam.fx * z, (v - cam.cy) / cam.fy * z, z], 1)


@dataclass
class Nets:
    """The networks being fine-tuned (``solver``/``depth`` None when not part of the run)."""

    sampler: SamplerNet
    solver: torch.nn.Module | None
    depth: torch.nn.Module | None

    def modules(self) -> dict[str, torch.nn.Module]:
        named = {"sampler": self.sampler, "solver": self.solver, "depth": self.depth}
        return {k: v for k, v in named.items() if v is not None}


def load_nets(cfg: FinetuneConfig, sampler_weights=None, solver_weights=None, depth_weights=None) -> Nets:
    """The pre-trained starting points (None = the shipped weights)."""
    from cuboidcli.solvers.neural import load_solver_net

    path = resolve("sampler", sampler_weights)
    if not path.is_file():
        raise FileNotFoundError(f"sampler weights {path} not found; train them with 'cuboids train sampler'")
    sampler = load_net(path, "sampler", sampler_from_checkpoint)
    if cfg.solver == "neural":
        solver = load_solver_net(default_path("solver") if solver_weights is None else solver_weights, "cpu")
    else:
        solver = None
    depth = None
    if cfg.rgb:
        from cuboidcli.nets.depth import net_from_checkpoint

        dpath = resolve("depth", depth_weights)
        if not dpath.is_file():
            raise FileNotFoundError(f"depth weights {dpath} not found; train them with 'cuboids train depth'")
        depth = load_net(dpath, "depth", net_from_checkpoint)
    return Nets(sampler, solver, depth)


def _solve(nets: Nets, numerical, sets: Tensor) -> tuple[Tensor, Tensor, Tensor]:
    if nets.solver is not None:
        c, a, r = nets.solver(sets.float())
        return c.double(), a.double(), r.double()
    from cuboidcli.solvers.implicit import implicit_cuboid_solve

    return implicit_cuboid_solve(sets.double(), numerical)


def scene_loss(
    nets: Nets, scene: Scene, cfg: FinetuneConfig, fit: FitConfig, numerical, gen: torch.Generator
) -> tuple[Tensor, list[dict]]:
    """The mean instance loss of one scene (with gradients) and one record of floats per instance."""
    from cuboidcli.geometry.fused import cuboid_values  # numba loads when training runs, not at start-up

    z = scene.z_points
    n = z.shape[0]
    if nets.depth is not None:
        grid = predicted_grid(nets.depth, scene)
        y = backproject_grid(grid, scene)
        depth_in = grid.float()
    else:
        y, depth_in = z, scene.depth_grid
    hs, ws = scene.grid_shape
    valid = torch.zeros(hs * ws, dtype=torch.bool)
    valid[scene.grid_index] = True
    valid = valid.view(1, hs, ws)
    state_y = torch.zeros(n, dtype=torch.float64)
    state_z = torch.zeros(n, dtype=torch.float64)
    kernel = (fit.tau_sq_m2, fit.beta, fit.tau_c)
    z32 = z.float()
    losses, records = [], []
    for _ in range(cfg.instances):
        state_grid = torch.zeros(hs * ws, dtype=torch.float32)
        state_grid[scene.grid_index] = state_y.float()
        out = nets.sampler(depth_in.view(1, hs, ws), state_grid.view(1, hs, ws), valid)
        log_p = out.log_p[0].flatten(1)[:, scene.grid_index]
        log_q = out.log_q[0]
        p, q = log_p.detach().exp().double(), log_q.detach().exp().double()
        expected, log_probs = [], []
        best = (-math.inf, None, None)
        for _k in range(cfg.samples_k):
            maps, idx = draw_sets_and_maps(p, q, cfg.hypotheses, fit.min_set, gen)
            c, a, r = _solve(nets, numerical, y[idx])
            # All |H| gains without gradients (the fused kernel), then the differentiable expectation over
            # the grad_top hypotheses of largest selection weight, the softmax renormalised over them.
            with torch.no_grad():
                v_all = torch.from_numpy(
                    cuboid_values(y.detach(), c.detach(), a.detach(), r.detach(), *kernel)
                )
                g_all = (combine(v_all, state_y[None]) - state_y[None]).sum(1) / n
            top = torch.topk(g_all, min(cfg.grad_top, g_all.shape[0])).indices
            c32, a32, r32 = c[top].float(), a[top].float(), r[top].float()
            # With RGB the gains on Y see the points as constants: the depth network learns through the
            # cuboids its points produce (judged on Z), not by moving every point onto the selected cuboid.
            y_count = y.float() if nets.depth is None else y.detach().float()
            v_y = oai_per_cuboid(y_count, c32, a32, r32, *kernel).double()  # (top, N)
            v_z = v_y if nets.depth is None else oai_per_cuboid(z32, c32, a32, r32, *kernel).double()
            gains = (combine(v_y, state_y[None]) - state_y[None]).sum(1) / n
            # the paper clamps losses to |0.3|: a hypothesis that hides many true points (the leaky
            # occlusion penalty is unbounded) would otherwise dominate the gradient of the expectation
            task = (-combine(v_z, state_z[None]).sum(1) / n).clamp(max=cfg.loss_clamp)
            expected.append((torch.softmax(cfg.alpha * gains, 0) * task).sum())
            log_probs.append(set_log_prob(log_p, log_q, maps, idx))
            g = gains.detach()
            if float(g[0]) > best[0]:  # topk is sorted: the first is the best of the set
                best = (float(g[0]), v_y[0].detach(), v_z[0].detach())
        e = torch.stack(expected)
        advantage = (e.detach() - e.detach().mean()).clamp(-cfg.loss_clamp, cfg.loss_clamp)
        loss = (advantage.float() * torch.stack(log_probs)).mean() + e.mean().float()
        if cfg.kappa_corr:
            free = out.log_p_free[0].flatten(1)[:, scene.grid_index].exp()
            loss = loss + cfg.kappa_corr * correlation_loss(free, cfg.corr_mode)
        if cfg.kappa_entropy:
            loss = loss + cfg.kappa_entropy * entropy_loss(log_q.exp())
        if cfg.kappa_im:
            loss = loss + cfg.kappa_im * inlier_masking_loss(log_p.exp(), state_y)
        losses.append(loss)
        records.append({"expected_loss": float(e.detach().mean()), "best_gain": best[0]})
        state_y = combine(best[1], state_y)
        state_z = combine(best[2], state_z)
    return torch.stack(losses).mean(), records


def validate(
    nets: Nets, frames: list[Frame], cfg: FinetuneConfig, fit: FitConfig, ctx: DistContext | None = None
) -> dict:
    """Fit the val frames with the current networks; the paper's metrics against the true depth.

    With an active ``ctx`` (a collective: every rank calls it) rank r fits frames r, r + W, ... and the
    per-frame metrics are gathered in frame order, so every rank returns the same numbers, equal to one
    process's; ``seconds`` is this rank's wall time."""
    from cuboidcli.evaluation.metrics import aggregate, frame_metrics
    from cuboidcli.solvers.neural import NeuralSolver
    from cuboidcli.solvers.numerical import NumericalSolver

    config = replace(fit, hypotheses=cfg.val_hypotheses, sampler="learned", grid_step=cfg.grid_step, seed=0)
    sampler = LearnedSampler(nets.sampler)
    if nets.solver is not None:
        solver = NeuralSolver(net=nets.solver)
    else:
        solver = NumericalSolver(lr=fit.solver_lr, iters=fit.solver_iters)
    estimator = None
    if nets.depth is not None:
        from cuboidcli.depth.estimator import BuiltinDepthEstimator

        estimator = BuiltinDepthEstimator(net=nets.depth)
    ctx = ctx or DistContext()
    mine = []
    start = time.perf_counter()
    for frame in ctx.share(frames):
        depth = frame.depth_m()
        fit_input = depth if estimator is None else estimator.predict(frame.rgb(), frame.camera)
        cuboids, _ = fit_depth(fit_input, frame.camera, config, solver=solver, sampler=sampler)
        mine.append(frame_metrics(frame.name, depth, frame.camera, cuboids))
    per_frame = ctx.gather_shares(mine, len(frames))
    for module in nets.modules().values():
        module.train()
    if nets.depth is not None:
        nets.depth.eval()
    out = aggregate(per_frame)
    out.pop("time_s", None)
    out["seconds"] = time.perf_counter() - start
    return out


class FinetuneJob(TrainingJob):
    """End-to-end fine-tuning as a job of :func:`~cuboidcli.learn.trainer.run_job`: epoch-based, B scenes a
    step split over the ranks; the starting weights are validated too and may stay the best."""

    name = "finetune"
    state_kind = STATE_KIND
    rate_key = "scenes_per_s"
    initial_is_candidate = True

    def __init__(self, cfg: FinetuneConfig, data: Path, weights: tuple, fit: FitConfig):
        self.cfg, self.data, self.weights, self.fit = cfg, data, weights, fit

    def setup(self, run: Run, state: dict | None) -> None:
        from cuboidcli.solvers.implicit import polished
        from cuboidcli.solvers.numerical import NumericalSolver

        cfg, fit = self.cfg, self.fit
        self.nets = nets = load_nets(cfg, *self.weights)
        if state is not None:
            for name, module in nets.modules().items():
                module.load_state_dict(state["nets"][name])
        for module in nets.modules().values():
            module.train()
        if nets.depth is not None:
            nets.depth.eval()
        rates = {
            "sampler": cfg.lr,
            "solver": cfg.lr if cfg.solver_lr is None else cfg.solver_lr,
            "depth": cfg.lr if cfg.depth_lr is None else cfg.depth_lr,
        }
        groups = []
        for name, module in nets.modules().items():
            module.requires_grad_(rates[name] > 0)  # a fixed network needs no gradients
            if rates[name] > 0:
                groups.append({"params": list(module.parameters()), "lr": rates[name]})
        if not groups:
            raise ValueError("every learning rate is 0: nothing to fine-tune")
        self.trained = [p for g in groups for p in g["params"]]
        self.optimizer = torch.optim.Adam(groups)
        self.gen = draw_generator(cfg.seed, run.ctx, state, run.epoch)
        self.numerical = polished(NumericalSolver(lr=fit.solver_lr, iters=fit.solver_iters))
        self._load_data()

    def _load_data(self) -> None:
        cfg, data = self.cfg, self.data
        train_frames, val_frames, self.split = dataset_splits(data)
        if cfg.val_frames is not None:
            val_frames = val_frames[: cfg.val_frames]
        self.val_frames = val_frames
        rgb_size = None
        if self.nets.depth is not None:
            rgb_size = (self.nets.depth.config.input_height, self.nets.depth.config.input_width)
        if cfg.workers > 1:
            from concurrent.futures import ThreadPoolExecutor

            with ThreadPoolExecutor(cfg.workers) as pool:
                loaded = list(pool.map(lambda f: load_scene(f, cfg.grid_step, rgb_size), train_frames))
        else:
            loaded = [load_scene(f, cfg.grid_step, rgb_size) for f in train_frames]
        self.scenes = [s for s in loaded if s is not None]
        if not self.scenes:
            raise ValueError(
                f"no usable training frames in {data} (each needs >= 6 valid points"
                + (" and an RGB image)" if cfg.rgb else ")")
            )
        if cfg.rgb and any(not _has_rgb(f) for f in val_frames):
            raise ValueError("fine-tuning from RGB needs RGB images for the val frames too")

    def batches(self, run: Run):
        cfg = self.cfg
        return batched(epoch_order(len(self.scenes), run.epoch, cfg.seed, cfg.scenes_per_epoch), cfg.batch)

    def step(self, run: Run, batch: list[int]) -> StepResult:
        cfg, fit = self.cfg, self.fit

        def one(i: int) -> list[dict]:
            # scaled by 1 / B of the global batch: the sum over the ranks is the global batch's gradient
            loss, records = scene_loss(self.nets, self.scenes[i], cfg, fit, self.numerical, self.gen)
            (loss / len(batch)).backward()
            return records

        mean = shared_batch_step(run.ctx, self.optimizer, self.trained, batch, one)
        return StepResult(mean, {"epoch": run.epoch + 1, "scenes": len(batch)}, items=len(batch))

    def validate(self, run: Run) -> Validation | None:
        if not self.val_frames:
            return None
        record = validate(self.nets, self.val_frames, self.cfg, self.fit, run.ctx)
        return Validation(float(record["auc20cm_pct"]), record)

    def state(self, run: Run) -> dict:
        return {
            "config": asdict(self.cfg),
            "fit_config": self.fit.to_dict(),
            "nets": {k: m.state_dict() for k, m in self.nets.modules().items()},
            **draw_states(self.gen, run.ctx),
        }

    def networks(self) -> dict[str, torch.nn.Module]:
        return self.nets.modules()

    def best_weights(self, run: Run, validation: dict) -> dict[str, dict]:
        """The networks under the names ``cuboids fit --weights DIR`` reads."""
        meta = {"finetune": asdict(self.cfg), "epoch": run.epoch, "val": validation, "data": str(self.data)}
        return {FILES[kind]: checkpoint_dict(net, meta) for kind, net in self.nets.modules().items()}

    def settings(self, run: Run) -> dict:
        return {
            "finetune": asdict(self.cfg),
            "fit": self.fit.to_dict(),
            "data": str(self.data),
            **self.start_fields(run),
        }

    def start_fields(self, run: Run) -> dict:
        return {"split": self.split, "train_frames": len(self.scenes), "val_frames": len(self.val_frames)}

    def end_fields(self, run: Run) -> dict:
        return {"epochs_done": run.epoch, "best": run.best}

    def agreement(self) -> object:
        return ([s.name for s in self.scenes], [f.name for f in self.val_frames])


#: Fields of the caller's config that replace the checkpoint's when resuming.
RESUME_OVERRIDES = ("epochs", "threads", "device", "max_minutes", "workers")


def finetune(
    cfg: FinetuneConfig,
    data: str | Path,
    out_dir: str | Path,
    sampler_weights: str | Path | None = None,
    solver_weights: str | Path | None = None,
    depth_weights: str | Path | None = None,
    resume: str | Path | None = None,
    on_event: Callable[[dict], None] | None = None,
    fit: FitConfig | None = None,
    backend: str | None = None,
) -> dict:
    """Fine-tune end to end (see the module docstring); returns the final record.

    ``*_weights``: starting points (None = the shipped ones). ``resume``: a ``last.pt`` of this trainer;
    the run's schedule and networks come from it, only the fields of ``cfg`` in :data:`RESUME_OVERRIDES`
    apply.

    Launched by ``torchrun`` with ``WORLD_SIZE > 1``, this joins the process group for the duration of
    the call (``backend``: None = gloo on the CPU, or ``$CUBOIDS_DIST_BACKEND``) and trains data parallel
    as the module docstring describes; every rank must pass the same arguments. Only rank 0 calls
    ``on_event`` and writes to ``out_dir``, which must be visible to every rank for ``resume``.
    """
    fit = fit or FitConfig()
    state, cfg = resumed(resume, cfg, RESUME_OVERRIDES, STATE_KIND, "fine-tuning", "OUT/last.pt", "config")
    if state is not None:
        fit = FitConfig(**state["fit_config"])
    run = RunConfig.of(cfg, out_dir, resume, max_epochs=cfg.epochs, backend=backend)
    weights = (sampler_weights, solver_weights, depth_weights)
    return run_job(FinetuneJob(cfg, Path(data), weights, fit), run, state, on_event)

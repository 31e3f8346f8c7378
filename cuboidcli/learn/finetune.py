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
The frames are read by :mod:`cuboidcli.learn.finetune_data`; the networks and the loss of a scene are
:mod:`cuboidcli.learn.finetune_loss`'s.

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
draws its hypotheses from its own generator (:func:`~cuboidcli.learn.draws.draw_seed`; rank 0
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

import time
from collections.abc import Callable
from dataclasses import asdict, replace
from pathlib import Path

import torch

from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import fit_depth
from cuboidcli.io.dataset import Frame
from cuboidcli.learn.distributed import DistContext
from cuboidcli.learn.draws import draw_generator, draw_states
from cuboidcli.learn.finetune_config import FinetuneConfig
from cuboidcli.learn.finetune_data import has_rgb, load_scene
from cuboidcli.learn.finetune_loss import Nets, load_nets, scene_loss
from cuboidcli.learn.job import StepResult, TrainingJob, Validation
from cuboidcli.learn.run_config import RunConfig
from cuboidcli.learn.sampler_data import dataset_splits, epoch_order
from cuboidcli.learn.trainer import Run, batched, run_job, shared_batch_step
from cuboidcli.learn.training_state import resumed
from cuboidcli.nets.checkpoint import checkpoint_dict
from cuboidcli.sampling.learned import LearnedSampler
from cuboidcli.weights import FILES

STATE_KIND = "finetune-state"
#: The files it writes, in the layout ``--weights DIR`` reads.
SAMPLER_NAME, SOLVER_NAME, DEPTH_NAME = FILES["sampler"], FILES["solver"], FILES["depth"]


def validate(
    nets: Nets, frames: list[Frame], cfg: FinetuneConfig, fit: FitConfig, ctx: DistContext | None = None
) -> dict:
    """Fit the val frames with the current networks; the paper's metrics against the true depth.

    With an active ``ctx`` (a collective: every rank calls it) rank r fits frames r, r + W, ... and the
    per-frame metrics are gathered in frame order, so every rank returns the same numbers, equal to one
    process's; ``seconds`` is this rank's wall time."""
    from cuboidcli.evaluation.aggregate import aggregate
    from cuboidcli.evaluation.metrics import frame_metrics
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
        if cfg.rgb and any(not has_rgb(f) for f in val_frames):
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

"""Training of the built-in depth network on an RGB-D dataset folder (the layout of ``cuboids synth``).

Loss over the valid ground-truth pixels (depth > 0) of each image: the scale-invariant log error of Eigen
et al. (2014), sqrt(mean g^2 - lambda (mean g)^2) with g = log d - log d*, averaged over the batch, plus
``l1_weight`` times the mean absolute depth error in metres (the scale-invariant term alone would leave
the metric scale to the (1 - lambda) share of its penalty).

Targets live in the net's canonical camera: the images are resized to the net's input size and each
frame's depth is multiplied by f_canonical / f_frame (f the geometric mean of the focal lengths at the
input size; 1 for a dataset written with one camera). Augmentation, drawn from a seeded generator:
a random crop of ``min_crop``..1 of the image resized back to the input size (it magnifies by 1 / s, so
the canonical depth of every pixel becomes s times its depth), a horizontal flip (the focal length, the
only intrinsic the target depends on, is unchanged; the principal point mirrors, which the net never
sees), and colour jitter (brightness, contrast, saturation).

The loop is :func:`cuboidcli.learn.trainer.run_job`'s (:class:`DepthJob`: epoch-based, one process).
Files in ``out_dir``: ``config.json``, ``log.jsonl`` (one record per logged step, validation and epoch),
``last.pt`` (training state: weights, optimizer, generator state, epoch; resume with it) and ``best.pt``
(weights-only checkpoint with the lowest validation AbsRel; the same file as ``depth_v2.pt`` too, the
name a weights folder holds the depth network under, :data:`cuboidcli.weights.FILES`). The library
prints nothing; progress goes to ``on_event``. The command line is ``cuboids train depth``
(:mod:`cuboidcli.cli.train_depth`).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Collection
from dataclasses import asdict, dataclass, replace
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F  # noqa: N812 - the usual alias

from cuboidcli.depth.estimator import BuiltinDepthEstimator
from cuboidcli.depth.evaluate import evaluate_frames
from cuboidcli.depth.image import resize
from cuboidcli.io.dataset import Frame, list_frames
from cuboidcli.learn.job import OneNetJob, StepResult, Validation
from cuboidcli.learn.run_config import RunConfig, RunFields, WarmupCosine
from cuboidcli.learn.trainer import Run, run_job
from cuboidcli.learn.training_state import resumed
from cuboidcli.nets.checkpoint import checkpoint_dict, parameter_count
from cuboidcli.nets.depth import DepthNet, DepthNetConfig
from cuboidcli.weights import FILES


@dataclass(frozen=True)
class DepthTrainConfig(WarmupCosine, RunFields):
    """Schedule, loss and augmentation of a training run; AdamW follows the :class:`WarmupCosine` schedule."""

    epochs: int = 60
    """Passes over the training split."""
    batch: int = 8
    """Images per optimizer step."""
    weight_decay: float = 1e-4
    warmup: int = 100
    grad_clip: float = 5.0
    silog_lambda: float = 0.85
    """lambda of the scale-invariant log loss (1 = fully scale invariant)."""
    l1_weight: float = 0.2
    """Weight of the mean absolute depth error, 1/m."""
    min_crop: float = 0.8
    """Smallest random crop, as a fraction of the image side (1 = no crop augmentation)."""
    flip: bool = True
    """Random horizontal flips."""
    jitter: float = 0.3
    """Colour jitter strength: factors drawn from [1 - jitter, 1 + jitter]."""
    white_balance: float = 0.0
    """Per-channel colour gains drawn from [1 - white_balance, 1 + white_balance] (camera white balance)."""
    blur: float = 0.0
    """Largest Gaussian blur sigma, pixels at the net's input; half the images are blurred (0 = none)."""
    noise: float = 0.0
    """Largest standard deviation of per-pixel Gaussian noise on the [0, 1] image (0 = none)."""
    grad_weight: float = 0.0
    """Weight of the multi-scale gradient-matching loss on log depth (shape and edges; 0 = off)."""
    init: str | None = None
    """Weights file (a checkpoint of this net) to start from instead of random weights."""
    log_every: int = 10
    """Print and log the training loss every N steps."""

    def __post_init__(self) -> None:
        for name in ("epochs", "batch", "threads", "log_every"):
            if getattr(self, name) < 1:
                raise ValueError(f"{name} must be at least 1, got {getattr(self, name)}")
        for name in ("lr", "grad_clip"):
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        for name in ("weight_decay", "warmup", "l1_weight", "final_lr_ratio", "blur", "noise", "grad_weight"):
            if not getattr(self, name) >= 0:
                raise ValueError(f"{name} must not be negative, got {getattr(self, name)}")
        if not 0 <= self.silog_lambda <= 1:
            raise ValueError(f"silog_lambda must lie in [0, 1], got {self.silog_lambda}")
        if not 0 < self.min_crop <= 1:
            raise ValueError(f"min_crop must lie in (0, 1] (1 = no crops), got {self.min_crop}")
        for name in ("jitter", "white_balance"):
            if not 0 <= getattr(self, name) < 1:
                raise ValueError(f"{name} must lie in [0, 1), got {getattr(self, name)}")
        if self.max_minutes is not None and not self.max_minutes > 0:
            raise ValueError(f"max_minutes must be positive, got {self.max_minutes}")
        if self.device != "cpu" and not self.device.startswith("cuda"):
            raise ValueError(f"device must be cpu or cuda[:N], got {self.device!r}")


STATE_KIND = "depth-train-state"
#: The weights of the lowest validation AbsRel, a plain weights file.
BEST = "best.pt"

RESUME_OVERRIDES = ("threads", "max_minutes", "log_every", "device")
"""Fields of the caller's config that replace the checkpoint's when resuming, unless told otherwise."""


def focal_at_input(camera, cfg: DepthNetConfig) -> float:
    """Geometric mean focal length (px) of ``camera`` after resizing its image to the net's input size."""
    return math.sqrt(
        camera.fx * cfg.input_width / camera.width * camera.fy * cfg.input_height / camera.height
    )


def load_split(frames: list[Frame], cfg: DepthNetConfig) -> tuple[torch.Tensor, torch.Tensor]:
    """Images and canonical-camera depth targets at the net's input size: uint8 (N, 3, h, w) and float32
    (N, 1, h, w) metres (0 = hole; nearest-neighbour resizing keeps holes holes)."""
    import cv2

    rgbs, depths = [], []
    for f in frames:
        rgb = f.rgb()
        if rgb is None:
            raise ValueError(f"frame {f.name} has no RGB image; the depth net trains on RGB-D frames")
        depth = f.depth_m()
        if depth.shape != (cfg.input_height, cfg.input_width):
            depth = cv2.resize(depth, (cfg.input_width, cfg.input_height), interpolation=cv2.INTER_NEAREST)
        depth = depth * (cfg.canonical_focal_px / focal_at_input(f.camera, cfg))
        rgbs.append(resize(rgb, cfg.input_height, cfg.input_width))
        depths.append(depth.astype(np.float32))
    rgb_t = torch.from_numpy(np.stack(rgbs)).permute(0, 3, 1, 2).contiguous()
    return rgb_t, torch.from_numpy(np.stack(depths))[:, None]


def augment(
    rgb: torch.Tensor, depth: torch.Tensor, cfg: DepthTrainConfig, gen: torch.Generator
) -> tuple[torch.Tensor, torch.Tensor]:
    """rgb (B, 3, h, w) in [0, 1] and depth (B, 1, h, w) m -> augmented copies (see the module docstring)."""
    b, _, h, w = rgb.shape
    out_rgb, out_depth = [], []
    for i in range(b):
        x, d = rgb[i : i + 1], depth[i : i + 1]
        s = cfg.min_crop + (1.0 - cfg.min_crop) * float(torch.rand((), generator=gen))
        if s < 1.0:
            ch, cw = max(8, round(s * h)), max(8, round(s * w))
            top = int(torch.randint(0, h - ch + 1, (), generator=gen))
            left = int(torch.randint(0, w - cw + 1, (), generator=gen))
            x = F.interpolate(x[..., top : top + ch, left : left + cw], size=(h, w), mode="bilinear")
            d = F.interpolate(d[..., top : top + ch, left : left + cw], size=(h, w), mode="nearest")
            d = d * (ch / h)  # magnified by h / ch: canonical depth shrinks by the same factor
        if cfg.flip and float(torch.rand((), generator=gen)) < 0.5:
            x, d = x.flip(-1), d.flip(-1)
        out_rgb.append(x)
        out_depth.append(d)
    x, d = torch.cat(out_rgb), torch.cat(out_depth)
    if cfg.jitter > 0:
        j = cfg.jitter
        factors = 1.0 + j * (2.0 * torch.rand(3, b, 1, 1, 1, generator=gen) - 1.0)
        x = x * factors[0]  # brightness
        mean = x.mean((1, 2, 3), keepdim=True)
        x = (x - mean) * factors[1] + mean  # contrast
        grey = x.mean(1, keepdim=True)
        x = (x - grey) * factors[2] + grey  # saturation
        x = x.clamp(0.0, 1.0)
    if cfg.white_balance > 0:
        gains = 1.0 + cfg.white_balance * (2.0 * torch.rand(b, 3, 1, 1, generator=gen) - 1.0)
        x = (x * gains).clamp(0.0, 1.0)
    if cfg.blur > 0:
        x = torch.cat([_blurred(x[i : i + 1], cfg.blur, gen) for i in range(b)])
    if cfg.noise > 0:
        sigma = cfg.noise * torch.rand(b, 1, 1, 1, generator=gen)
        x = (x + sigma * torch.randn(x.shape, generator=gen)).clamp(0.0, 1.0)
    return x, d


def _blurred(x: torch.Tensor, max_sigma: float, gen: torch.Generator) -> torch.Tensor:
    """x (1, 3, h, w) blurred with a Gaussian of sigma drawn from [0, max_sigma] px, or as it is (even odds):
    real photos are softer than the renders (optics, motion, JPEG)."""
    if float(torch.rand((), generator=gen)) < 0.5:
        return x
    sigma = max_sigma * float(torch.rand((), generator=gen))
    radius = math.ceil(2.5 * sigma)
    if radius < 1:
        return x
    t = torch.arange(-radius, radius + 1, dtype=x.dtype)
    k = torch.exp(-0.5 * (t / sigma) ** 2)
    k = k / k.sum()
    x = F.pad(x, (radius, radius, radius, radius), mode="replicate")
    x = F.conv2d(x, k.view(1, 1, 1, -1).expand(3, 1, 1, -1), groups=3)
    return F.conv2d(x, k.view(1, 1, -1, 1).expand(3, 1, -1, 1), groups=3)


def depth_loss(pred: torch.Tensor, target: torch.Tensor, cfg: DepthTrainConfig) -> torch.Tensor:
    """Scale-invariant log loss + l1_weight * L1 over valid pixels: pred, target (B, 1, h, w) m -> scalar."""
    valid = target > 0
    safe_target = torch.where(valid, target, torch.ones_like(target))
    g = torch.where(valid, pred.log() - safe_target.log(), torch.zeros_like(pred))
    n = valid.sum((1, 2, 3)).clamp_min(1)
    mean_g = g.sum((1, 2, 3)) / n
    mean_g2 = (g * g).sum((1, 2, 3)) / n
    silog = (mean_g2 - cfg.silog_lambda * mean_g**2).clamp_min(1e-8).sqrt()
    l1 = torch.where(valid, (pred - target).abs(), torch.zeros_like(pred)).sum() / valid.sum().clamp_min(1)
    loss = silog.mean() + cfg.l1_weight * l1
    if cfg.grad_weight > 0:
        loss = loss + cfg.grad_weight * gradient_loss(g, valid)
    return loss


#: Scales of the gradient-matching loss: the log-depth error at full, 1/2, 1/4 and 1/8 resolution.
GRAD_SCALES = 4


def gradient_loss(g: torch.Tensor, valid: torch.Tensor) -> torch.Tensor:
    """Multi-scale gradient matching (Li & Snavely, MegaDepth 2018): the mean absolute x and y differences of
    the log-depth error ``g`` (B, 1, h, w; 0 off ``valid``) between valid neighbours, summed over
    :data:`GRAD_SCALES` scales. A global scale error has no gradient, so this term only sees the shape:
    a plane predicted tilted or a step smeared across an object's boundary."""
    total = g.new_zeros(())
    for k in range(GRAD_SCALES):
        if k:
            g, valid = g[..., ::2, ::2], valid[..., ::2, ::2]
        vx = valid[..., :, 1:] & valid[..., :, :-1]
        vy = valid[..., 1:, :] & valid[..., :-1, :]
        dx = torch.where(vx, (g[..., :, 1:] - g[..., :, :-1]).abs(), torch.zeros_like(g[..., :, 1:]))
        dy = torch.where(vy, (g[..., 1:, :] - g[..., :-1, :]).abs(), torch.zeros_like(g[..., 1:, :]))
        total = total + (dx.sum() + dy.sum()) / (vx.sum() + vy.sum()).clamp_min(1)
    return total


def read_init(path: str | Path) -> tuple[DepthNetConfig, dict]:
    """The configuration and state dict of the depth-network weights file ``path`` (``--init``); its
    canonical focal length comes with it (the targets are scaled to it)."""
    try:
        ckpt = torch.load(path, map_location="cpu", weights_only=True)
    except Exception as e:  # noqa: BLE001 - any unreadable file gets the same one-line answer
        raise ValueError(f"cannot read --init {path}: {e}") from None
    if not isinstance(ckpt, dict) or "state_dict" not in ckpt or "config" not in ckpt:
        raise ValueError(f"--init {path} is not a weights file of the depth network (no config / state_dict)")
    return DepthNetConfig.from_dict(ckpt["config"]), ckpt["state_dict"]


class DepthJob(OneNetJob):
    """Training of the depth network as a job of :func:`~cuboidcli.learn.trainer.run_job`: epoch-based, in
    one process, validated after every epoch on the val split."""

    name = "depth"
    net_name = "depth"
    state_kind = STATE_KIND
    step_event = "train"
    end_event = "done"
    rate_key = "images_per_s"
    lower_is_better = True
    distributed = False

    def __init__(self, cfg: DepthTrainConfig, data: str | Path, net_cfg: DepthNetConfig | None):
        self.cfg, self.data, self.net_cfg = cfg, data, net_cfg

    def setup(self, run: Run, state: dict | None) -> None:
        cfg, data = self.cfg, self.data
        train_frames, val_frames = list_frames(data, "train"), list_frames(data, "val")
        if not train_frames:
            raise ValueError(f"{data}'s train split is empty")
        if len(train_frames) < cfg.batch:
            raise ValueError(
                f"batch {cfg.batch} is larger than the {len(train_frames)} frames of {data}'s train split"
            )
        if not val_frames:
            raise ValueError(f"{data}'s val split is empty; validation picks best.pt")
        no_rgb = [f.name for f in val_frames if f.rgb_path is None]
        if no_rgb:
            raise ValueError(f"val frame {no_rgb[0]} has no RGB image; the depth net trains on RGB-D frames")
        self.train_frames, self.val_frames = train_frames, val_frames
        net_cfg = self.net_cfg or DepthNetConfig()
        init_weights = None
        if state is None and cfg.init is not None:
            net_cfg, init_weights = read_init(cfg.init)
        elif state is None:
            net_cfg = replace(net_cfg, canonical_focal_px=focal_at_input(train_frames[0].camera, net_cfg))
        self.net_cfg = net_cfg
        self.rgb_all, self.depth_all = load_split(train_frames, net_cfg)
        self.net = DepthNet(net_cfg).to(run.device)
        self.optimizer = torch.optim.AdamW(self.net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
        self.gen = torch.Generator().manual_seed(cfg.seed)
        if state is not None:
            self.net.load_state_dict(state["state_dict"])
            self.gen.set_state(state["generator"])
        elif init_weights is not None:
            self.net.load_state_dict(init_weights)
        self.steps_per_epoch = len(train_frames) // cfg.batch
        self.total_steps = self.steps_per_epoch * cfg.epochs

    def batches(self, run: Run):
        self.net.train()
        order = torch.randperm(len(self.train_frames), generator=self.gen)
        b = self.cfg.batch
        return (order[k * b : (k + 1) * b] for k in range(self.steps_per_epoch))

    def step(self, run: Run, idx: torch.Tensor) -> StepResult:
        cfg, net, opt = self.cfg, self.net, self.optimizer
        x, target = augment(self.rgb_all[idx].float() / 255.0, self.depth_all[idx], cfg, self.gen)
        x, target = x.to(run.device), target.to(run.device)
        lr = cfg.lr_at(run.step, self.total_steps, run.time_fraction())
        for group in opt.param_groups:
            group["lr"] = lr
        loss = depth_loss(net(net.normalise(x)), target, cfg)
        opt.zero_grad(set_to_none=True)
        loss.backward()
        grad_norm = torch.nn.utils.clip_grad_norm_(net.parameters(), cfg.grad_clip)
        opt.step()
        fields = {"epoch": run.epoch, "lr": lr, "grad_norm": float(grad_norm)}
        return StepResult({"loss": loss.item()}, fields, items=cfg.batch)

    def validate(self, run: Run) -> Validation:
        estimator = BuiltinDepthEstimator(net=self.net, device=run.device)
        self.val = evaluate_frames(estimator, self.val_frames)["mean"]
        return Validation(self.val["abs_rel"], self.val)

    def more_state(self, run: Run) -> dict:
        return {"generator": self.gen.get_state()}

    def best_weights(self, run: Run, validation: dict) -> dict[str, dict]:
        meta = {
            "epoch": run.epoch,
            "step": run.step,
            "validation": validation,
            "parameters": parameter_count(self.net),
            "train_config": asdict(self.cfg),
            "data": str(self.data),
            "elapsed_s": run.elapsed(),
        }
        weights = checkpoint_dict(self.net, meta)
        return {BEST: weights, FILES["depth"]: weights}

    def settings(self, run: Run) -> dict:
        settings = {"data": str(self.data), "train": asdict(self.cfg), "net": self.net_cfg.to_dict()}
        return {**settings, "frames": {"train": len(self.train_frames), "val": len(self.val_frames)}}

    def start_fields(self, run: Run) -> dict:
        return {
            "batch": self.cfg.batch,
            "steps_per_epoch": self.steps_per_epoch,
            "train_frames": len(self.train_frames),
            "val_frames": len(self.val_frames),
            "device": str(run.device),
        }

    def end_fields(self, run: Run) -> dict:
        return {"best_abs_rel": run.best, "best": str(run.out_dir / BEST)}


def train_depth(
    data: str | Path,
    out_dir: str | Path,
    cfg: DepthTrainConfig | None = None,
    net_cfg: DepthNetConfig | None = None,
    resume: str | Path | None = None,
    on_event: Callable[[dict], None] | None = None,
    resume_overrides: Collection[str] = RESUME_OVERRIDES,
) -> dict:
    """Train (or resume) on ``data``'s train split, validating on its val split after every epoch.

    The net's canonical focal length is that of the first training frame at the input size. When
    resuming, schedule and net come from the checkpoint except the fields of ``cfg`` named in
    ``resume_overrides`` (by default ``threads``, ``max_minutes``, ``log_every`` and ``device``; add
    ``epochs`` to extend a finished run, which also stretches the cosine decay).
    Returns the final record (epoch, best validation AbsRel, paths).
    """
    cfg = cfg or DepthTrainConfig()
    state, cfg = resumed(resume, cfg, resume_overrides, STATE_KIND, "depth training")
    if state is not None:
        net_cfg = DepthNetConfig.from_dict(state["config"])
    run = RunConfig.of(
        cfg, out_dir, resume, max_epochs=cfg.epochs, stop_within_epoch=True, minutes_span_resumes=True
    )
    return run_job(DepthJob(cfg, data, net_cfg), run, state, on_event)

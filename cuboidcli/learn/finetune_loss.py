"""The networks end-to-end fine-tuning trains (:class:`Nets`) and the loss of one scene through them
(:func:`scene_loss`, the gradient estimate :mod:`cuboidcli.learn.finetune` describes)."""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import torch
import torch.nn.functional as F  # noqa: N812 - the usual alias
from torch import Tensor

from cuboidcli.fitting.config import FitConfig
from cuboidcli.geometry.kernels import combine, oai_per_cuboid
from cuboidcli.io.checkpoints import load_net
from cuboidcli.learn.finetune_data import Scene
from cuboidcli.learn.sampler_loss import (
    correlation_loss,
    entropy_loss,
    inlier_masking_loss,
    set_log_prob,
)
from cuboidcli.nets.sampler import SamplerNet
from cuboidcli.nets.sampler import net_from_checkpoint as sampler_from_checkpoint
from cuboidcli.sampling import draw_sets_and_maps
from cuboidcli.weights import default_path, resolve

if TYPE_CHECKING:
    from cuboidcli.learn.finetune_config import FinetuneConfig


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

"""The sampling-weight network (paper Sec. 3.2.1, appendix "Sampling Weight Network").

Input, per frame on the fitting grid (Hs, Ws) (60x80 for NYU): the depth normalised by the training set's
mean and standard deviation (0 where invalid) and the state s = f_OAI(y, M) of the cuboids selected so far
(negative where occluded, 0 before the first cuboid and where invalid). Both channels are upsampled by an
integer factor (nearest) and a conv trunk with instance normalisation and residual blocks brings them back
down with stride-2 convolutions, so the output lies on the fitting grid again. With ``upsample = 8`` this
is the paper's layout (480x640 input, stride 8). The default (upsample 4: 240x320, 96 channels on the
grid) has ~0.19 M parameters and takes ~0.15 s for a forward and backward pass on one CPU thread, against
~11 M parameters in the paper.

Output: Q sampling-weight maps p_1..p_Q, each softmax-normalised over the VALID cells of its frame
(invalid cells get probability 0), and selection weights q (Q,) from global average pooling of the
penultimate features and a linear layer, also softmax-normalised. The paper applies sigmoids and then
normalises; softmax over logits is the same family and gives the log-probabilities the policy gradient
needs without a division. Weights are plain dicts ``{"config", "state_dict", "meta"}`` loaded with
``torch.load(weights_only=True)``.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F
from torch import Tensor, nn

from cuboidcli.nets.checkpoint import NetConfig, build_net

#: Sampling priors the network's maps can be built on (see SamplerNetConfig.prior).
PRIORS = ("none", "unexplained")


@dataclass(frozen=True)
class SamplerNetConfig(NetConfig):
    """Shape of the network and its input normalisation."""

    label = "sampler-net"

    maps: int = 4
    """Q: sampling-weight maps (4 in the paper)."""
    width: int = 96
    """Channels of the trunk at the fitting-grid resolution (halved per doubling of the resolution)."""
    blocks: int = 4
    """Residual blocks at the fitting-grid resolution (dilations 1, 2, 4, 8, 1, ...)."""
    upsample: int = 4
    """The input is the fitting grid upsampled by this power of two; log2(upsample) stride-2 layers bring
    it back (8 = the paper's 480x640 input with a stride-8 output)."""
    depth_mean_m: float = 3.0
    """Mean valid depth of the training set, metres (input normalisation, set by the trainer)."""
    depth_std_m: float = 1.5
    """Standard deviation of the valid depths of the training set, metres."""
    state_clip: float = 1.0
    """The state channel is clipped to [-state_clip, state_clip]: the leaky occlusion penalty is unbounded
    and a few strongly occluded points would otherwise dominate the instance statistics."""
    prior: str = "none"
    """"none": the maps are softmax(logits) (the paper). "unexplained": the maps are
    softmax(logits + log max(1 - max(s, 0), prior_floor)), i.e. the network predicts a log-weight
    correction on top of the sequential sampler's weights (points the selected cuboids explain are
    sampled less). With the map head initialised near zero an untrained net samples like the sequential
    sampler, and training starts from that instead of from uniform sampling."""
    prior_floor: float = 1e-3
    """Smallest prior weight: fully explained points keep this much (times exp(logit)) of a weight."""

    def __post_init__(self) -> None:
        if self.upsample < 1 or self.upsample & (self.upsample - 1):
            raise ValueError(f"upsample must be a power of two, got {self.upsample}")
        if self.maps < 1:
            raise ValueError(f"maps (Q) must be at least 1, got {self.maps}")
        if self.prior not in PRIORS:
            raise ValueError(f"prior must be one of {PRIORS}, got {self.prior!r}")
        if not 0.0 < self.prior_floor <= 1.0:
            raise ValueError(f"prior_floor must be in (0, 1], got {self.prior_floor}")


def _conv_in_relu(cin: int, cout: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(cin, cout, 3, stride=stride, padding=1),
        nn.InstanceNorm2d(cout, affine=True),
        nn.ReLU(inplace=True),
    )


class ResBlock(nn.Module):
    """Bottleneck residual block: 1x1 (width -> width/2), dilated 3x3, 1x1 (-> width), each with instance
    norm, ReLU after the sum. The dilation widens the receptive field on the coarse fitting grid for free
    (NG-RANSAC's blocks are not dilated; with blocks dilated 1, 2, 4, 8 a cell sees +-30 grid cells)."""

    def __init__(self, width: int, dilation: int = 1) -> None:
        super().__init__()
        mid = max(width // 2, 8)
        self.body = nn.Sequential(
            nn.Conv2d(width, mid, 1),
            nn.InstanceNorm2d(mid, affine=True),
            nn.ReLU(inplace=True),
            nn.Conv2d(mid, mid, 3, padding=dilation, dilation=dilation),
            nn.InstanceNorm2d(mid, affine=True),
            nn.ReLU(inplace=True),
            nn.Conv2d(mid, width, 1),
            nn.InstanceNorm2d(width, affine=True),
        )

    def forward(self, x: Tensor) -> Tensor:
        return torch.relu(x + self.body(x))


@dataclass
class SamplerOutput:
    """Network output for B frames on the fitting grid.

    ``log_p`` (B, Q, Hs, Ws): log sampling weights, -inf at invalid cells; ``p`` (B, Q, Hs, Ws): the
    weights, each map summing to 1 over the valid cells of its frame; ``log_q`` (B, Q) and ``q`` (B, Q):
    selection weights. ``log_p_free`` (B, Q, Hs, Ws): the maps without the sampling prior (the same as
    ``log_p`` for ``prior="none"``); the correlation regulariser looks at these, since the prior is a
    factor all maps share and no training can decorrelate.
    """

    log_p: Tensor
    p: Tensor
    log_q: Tensor
    q: Tensor
    log_p_free: Tensor


class SamplerNet(nn.Module):
    """(depth (B, Hs, Ws) m, state (B, Hs, Ws), valid (B, Hs, Ws) bool) -> :class:`SamplerOutput`."""

    def __init__(self, config: SamplerNetConfig | None = None) -> None:
        super().__init__()
        self.config = cfg = config or SamplerNetConfig()
        down = int(math.log2(cfg.upsample))
        # channels double as the resolution halves: width / 2^down at the input, width on the grid
        chans = [max(cfg.width >> (down - i), 8) for i in range(down + 1)]
        layers = [_conv_in_relu(2, chans[0])]
        layers += [_conv_in_relu(chans[i], chans[i + 1], stride=2) for i in range(down)]
        layers += [ResBlock(cfg.width, dilation=2 ** (i % 4)) for i in range(cfg.blocks)]
        self.trunk = nn.Sequential(*layers)
        self.penultimate = nn.Sequential(nn.Conv2d(cfg.width, cfg.width, 1), nn.ReLU(inplace=True))
        self.map_head = nn.Conv2d(cfg.width, cfg.maps, 1)
        self.q_head = nn.Linear(cfg.width, cfg.maps)
        if cfg.prior != "none":
            # start close to the prior; small distinct weights break the symmetry between the Q maps
            nn.init.normal_(self.map_head.weight, std=1e-2)
            nn.init.zeros_(self.map_head.bias)

    def encode(self, depth_m: Tensor, state: Tensor, valid: Tensor) -> Tensor:
        """The normalised 2-channel input at the network's resolution: (B, 2, up*Hs, up*Ws)."""
        cfg = self.config
        d = torch.where(valid, (depth_m - cfg.depth_mean_m) / cfg.depth_std_m, torch.zeros_like(depth_m))
        s = torch.where(valid, state.clamp(-cfg.state_clip, cfg.state_clip), torch.zeros_like(state))
        x = torch.stack([d, s], 1)
        if cfg.upsample > 1:
            x = F.interpolate(x, scale_factor=cfg.upsample, mode="nearest")
        return x

    def forward(self, depth_m: Tensor, state: Tensor, valid: Tensor) -> SamplerOutput:
        feat = self.penultimate(self.trunk(self.encode(depth_m, state, valid)))  # (B, width, Hs, Ws)
        if feat.shape[-2:] != depth_m.shape[-2:]:
            raise ValueError(f"grid {tuple(depth_m.shape[-2:])} does not survive the stride-2 layers")
        logits = self.map_head(feat)  # (B, Q, Hs, Ws)
        invalid = ~valid.flatten(1)[:, None, :]
        flat = logits.flatten(2).masked_fill(invalid, float("-inf"))
        log_p_free = torch.log_softmax(flat, -1).view_as(logits)
        log_p = log_p_free
        if self.config.prior == "unexplained":
            unexplained = (1.0 - state.clamp(0.0, 1.0)).clamp_min(self.config.prior_floor)
            flat = flat + torch.log(unexplained).flatten(1)[:, None, :]
            log_p = torch.log_softmax(flat, -1).view_as(logits)
        log_q = torch.log_softmax(self.q_head(feat.mean((-2, -1))), -1)  # global average pooling + FC
        return SamplerOutput(log_p=log_p, p=log_p.exp(), log_q=log_q, q=log_q.exp(), log_p_free=log_p_free)


def net_from_checkpoint(ckpt: dict) -> SamplerNet:
    """Rebuild the exact net of a checkpoint dict, in eval mode, on the CPU."""
    return build_net(ckpt, SamplerNet, SamplerNetConfig, "sampler")

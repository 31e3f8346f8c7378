"""The cuboid regression network (paper Sec. 3.2.3, appendix "Neural Cuboid Solver").

A minimal set S of C points (B, C, 3) in metres is centred by its mean mu_S and scaled by a fixed factor,
lifted to ``width`` channels by a per-point linear layer (the paper's 1x1 convolution), passed through
transformer encoder layers without positional encoding, mean-pooled over the points (so the output does
not depend on their order), and mapped by two fully connected layers to three heads:

- rotation: a 6D vector (Zhou et al. 2019) turned into R by Gram-Schmidt,
- translation: t = tanh(t~) * a_max + mu_S,
- half-sizes: a = sigmoid(a~) * (a_max - a_min) + a_min.

The paper's network is 128 wide with 4 layers and a 2048-wide feed-forward block (about 2.4 M parameters);
inside RANSAC it runs on 4096 x 6 points per step, which costs about 2 s on one core of a small CPU. The
defaults here (64 wide, 2 layers, 76 k parameters) cost about 90 ms of one core; the shapes of the layers
are kept in the checkpoint so that loading rebuilds the exact net. Dropout is not used at all (the
research code ran it at test time by accident).
"""

from __future__ import annotations

from dataclasses import dataclass

import torch
from torch import Tensor, nn

from cuboidcli.geometry.rotations import rotation_6d_to_matrix
from cuboidcli.nets.checkpoint import NetConfig, build_net


@dataclass(frozen=True)
class SolverNetConfig(NetConfig):
    """Shape of the network and the size bounds its output heads are scaled to."""

    label = "solver-net"

    width: int = 64
    """d: channels of the per-point features."""
    layers: int = 2
    """Transformer encoder layers (4 in the paper)."""
    heads: int = 4
    """Attention heads per layer; must divide ``width`` (8 in the paper)."""
    ff: int = 128
    """Hidden size of each layer's feed-forward block (2048 in the paper, PyTorch's default)."""
    a_min: float = 1e-3
    """a_min: smallest half-size the size head can produce, m (indoor value)."""
    a_max: float = 2.0
    """a_max: largest half-size, m; also the scale of the translation head (indoor value)."""
    input_scale: float = 0.5
    """Factor applied to the centred points so that the net sees O(1) values, 1/m (1 / a_max)."""


class EncoderLayer(nn.Module):
    """Pre-norm transformer encoder layer on (B, C, d) point features, no dropout.

    Written out instead of ``nn.TransformerEncoderLayer``: with only C = 6 tokens, PyTorch's softmax kernel
    over a last dimension of 6 dominated the runtime on CPU; the explicit max-subtracted exponential is
    several times faster, and the plain ops export to ONNX without special cases.
    """

    def __init__(self, width: int, heads: int, ff: int) -> None:
        super().__init__()
        if width % heads:
            raise ValueError(f"width {width} is not divisible by heads {heads}")
        self.heads = heads
        self.norm1 = nn.LayerNorm(width)
        self.qkv = nn.Linear(width, 3 * width)
        self.proj = nn.Linear(width, width)
        self.norm2 = nn.LayerNorm(width)
        self.ff1 = nn.Linear(width, ff)
        self.ff2 = nn.Linear(ff, width)

    def forward(self, x: Tensor) -> Tensor:
        b, c, d = x.shape
        dh = d // self.heads
        qkv = self.qkv(self.norm1(x))  # (B, C, 3d): [q heads | k heads | v heads]
        heads = []
        for h in range(self.heads):
            # per-head slices feed batched matmuls directly: no permute/contiguous copies of (B, C, 3d),
            # which took a third of the time with the usual (B, heads, C, dh) layout at C = 6
            q = qkv[..., h * dh : (h + 1) * dh]
            k = qkv[..., d + h * dh : d + (h + 1) * dh]
            v = qkv[..., 2 * d + h * dh : 2 * d + (h + 1) * dh]
            s = torch.bmm(q, k.transpose(1, 2)) * dh**-0.5  # (B, C, C)
            w = (s - s.amax(-1, keepdim=True)).exp()
            heads.append(torch.bmm(w / w.sum(-1, keepdim=True), v))
        att = heads[0] if self.heads == 1 else torch.cat(heads, -1)
        x = x + self.proj(att)
        # relu in place: one allocation fewer, and ReLU's backward only needs its output
        return x + self.ff2(torch.relu_(self.ff1(self.norm2(x))))


class SolverNet(nn.Module):
    """Minimal sets (B, C, 3), metres -> (centers (B, 3) m, half_sizes (B, 3) m, rotations (B, 3, 3)).

    Half-sizes lie in [a_min, a_max]; rotations are proper (det +1) with the cuboid's local axes as columns.
    The output does not depend on the order of the C points. Works for any C >= 1.
    """

    def __init__(self, config: SolverNetConfig | None = None) -> None:
        super().__init__()
        self.config = cfg = config or SolverNetConfig()
        self.embed = nn.Linear(3, cfg.width)  # the 1x1 convolution: the same linear map for every point
        self.encoder = nn.ModuleList(EncoderLayer(cfg.width, cfg.heads, cfg.ff) for _ in range(cfg.layers))
        self.norm = nn.LayerNorm(cfg.width)  # pre-norm layers leave the residual stream unnormalised
        d = cfg.width
        self.fc = nn.Sequential(nn.Linear(d, d), nn.ReLU(), nn.Linear(d, d), nn.ReLU())
        self.rot_head = nn.Linear(cfg.width, 6)
        self.trans_head = nn.Linear(cfg.width, 3)
        self.size_head = nn.Linear(cfg.width, 3)

    def forward(self, minimal_sets: Tensor) -> tuple[Tensor, Tensor, Tensor]:
        cfg = self.config
        mean = minimal_sets.mean(1)  # mu_S, (B, 3)
        x = self.embed((minimal_sets - mean[:, None, :]) * cfg.input_scale)
        for layer in self.encoder:
            x = layer(x)
        feat = self.fc(self.norm(x).mean(1))  # (B, d), mean pooling over the points
        rotations = rotation_6d_to_matrix(self.rot_head(feat))
        centers = torch.tanh(self.trans_head(feat)) * cfg.a_max + mean
        half_sizes = torch.sigmoid(self.size_head(feat)) * (cfg.a_max - cfg.a_min) + cfg.a_min
        return centers, half_sizes, rotations


def net_from_checkpoint(ckpt: dict) -> SolverNet:
    """Rebuild the exact net of a checkpoint dict, in eval mode, on the CPU."""
    return build_net(ckpt, SolverNet, SolverNetConfig, "solver")

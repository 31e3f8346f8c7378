"""The built-in monocular depth network f_v (paper Sec. 3: "a depth estimator realised as a CNN").

A small U-Net sized for a 2-core CPU: an encoder of strided 3x3 convolutions (five scales, 1/2 to 1/32 of
the input), a decoder that upsamples bilinearly and fuses the skip connection of each scale, and a head at
1/2 resolution whose output is upsampled bilinearly to the input size. Batch norm after every convolution.

Output: metric depth in metres, ``(B, 1, H, W)`` for an input ``(B, 3, H, W)``. The head predicts
log-depth through a sigmoid that spans [log min_depth_m, log max_depth_m], so the depth is always positive
and bounded and the network's raw output is well scaled (an error of x % is the same step everywhere).

Metric depth from a single image depends on the focal length: the net is trained for one *canonical*
camera (``canonical_focal_px`` at the input resolution). :class:`~cuboidcli.depth.estimator.
BuiltinDepthEstimator` rescales the prediction for other cameras (depth ~ focal length at a fixed
apparent size), as canonical-camera metric depth estimators do.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import torch
import torch.nn.functional as F  # noqa: N812 - the usual alias
from torch import Tensor, nn

from cuboidcli.nets.checkpoint import NetConfig, build_net

#: ImageNet statistics, the usual RGB normalisation; kept in the config so a checkpoint is self-contained.
IMAGENET_MEAN = (0.485, 0.456, 0.406)
IMAGENET_STD = (0.229, 0.224, 0.225)


@dataclass(frozen=True)
class DepthNetConfig(NetConfig):
    """Shape of the network, its input size and the output range. Stored in every checkpoint."""

    label = "depth-net"

    channels: tuple[int, ...] = (16, 32, 64, 128, 192)
    """Encoder channels at 1/2, 1/4, 1/8, 1/16 and 1/32 of the input resolution."""
    input_height: int = 240
    """Images are resized to input_height x input_width pixels before the forward pass."""
    input_width: int = 320
    canonical_focal_px: float = 259.58
    """Focal length (pixels, at the input resolution) of the camera the net was trained for: NYU's
    ~519 px at 640x480 halved, as written by ``cuboids synth --width 320``."""
    min_depth_m: float = 0.1
    """Lower end of the output range, m."""
    max_depth_m: float = 20.0
    """Upper end of the output range, m."""
    mean: tuple[float, float, float] = IMAGENET_MEAN
    """Per-channel mean subtracted from RGB in [0, 1]."""
    std: tuple[float, float, float] = IMAGENET_STD
    """Per-channel standard deviation RGB in [0, 1] is divided by."""


def _conv_bn_relu(c_in: int, c_out: int, stride: int = 1) -> nn.Sequential:
    return nn.Sequential(
        nn.Conv2d(c_in, c_out, 3, stride=stride, padding=1, bias=False),
        nn.BatchNorm2d(c_out),
        nn.ReLU(inplace=True),
    )


class DepthNet(nn.Module):
    """Normalised RGB ``(B, 3, H, W)`` -> metric depth ``(B, 1, H, W)`` in metres, for any H, W >= 32.

    The input is expected at the configured size and already normalised (see :meth:`normalise`);
    other sizes work (the decoder aligns the scales by interpolation) but the depth scale was learnt at
    the configured size.
    """

    def __init__(self, config: DepthNetConfig | None = None) -> None:
        super().__init__()
        self.config = cfg = config or DepthNetConfig()
        ch = cfg.channels
        self.encoder = nn.ModuleList()
        c_prev = 3
        for c in ch:  # each scale: a strided conv halves the resolution, a second conv refines
            self.encoder.append(nn.Sequential(_conv_bn_relu(c_prev, c, stride=2), _conv_bn_relu(c, c)))
            c_prev = c
        self.decoder = nn.ModuleList()
        for c_skip in reversed(ch[:-1]):  # fuse upsampled deeper features with the skip of each scale
            self.decoder.append(_conv_bn_relu(c_prev + c_skip, c_skip))
            c_prev = c_skip
        self.head = nn.Conv2d(c_prev, 1, 3, padding=1)
        self.register_buffer("_mean", torch.tensor(cfg.mean).view(1, 3, 1, 1), persistent=False)
        self.register_buffer("_std", torch.tensor(cfg.std).view(1, 3, 1, 1), persistent=False)

    def normalise(self, rgb01: Tensor) -> Tensor:
        """RGB in [0, 1] ``(B, 3, H, W)`` -> the network's input."""
        return (rgb01 - self._mean) / self._std

    def forward(self, x: Tensor) -> Tensor:
        cfg = self.config
        size = x.shape[-2:]
        skips = []
        for stage in self.encoder:
            x = stage(x)
            skips.append(x)
        x = skips.pop()
        for fuse in self.decoder:
            skip = skips.pop()
            # odd sizes (15 -> 8 rows) make the scales differ by one pixel: interpolate to the skip's size
            x = F.interpolate(x, size=skip.shape[-2:], mode="bilinear", align_corners=False)
            x = fuse(torch.cat([x, skip], 1))
        lo, hi = math.log(cfg.min_depth_m), math.log(cfg.max_depth_m)
        log_depth = lo + (hi - lo) * torch.sigmoid(self.head(x))
        log_depth = F.interpolate(log_depth, size=size, mode="bilinear", align_corners=False)
        return log_depth.exp()


def net_from_checkpoint(ckpt: dict) -> DepthNet:
    """Rebuild the exact net of a checkpoint dict, in eval mode, on the CPU."""
    return build_net(ckpt, DepthNet, DepthNetConfig, "depth-net")

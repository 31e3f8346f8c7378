"""The depth network's training loss and augmentation (cuboidcli.learn.depth_train)."""

from __future__ import annotations

import torch

from cuboidcli.learn.depth_train import DepthTrainConfig, augment, depth_loss, gradient_loss


def _plane(h=32, w=40, tilt=0.0):
    y, x = torch.meshgrid(
        torch.arange(h, dtype=torch.float32), torch.arange(w, dtype=torch.float32), indexing="ij"
    )
    return (2.0 + tilt * x / w)[None, None]


def test_gradient_loss_sees_shape_not_scale():
    target = _plane(tilt=1.0)
    valid = torch.ones_like(target, dtype=torch.bool)
    scaled = (target * 1.7).log() - target.log()
    assert gradient_loss(scaled, valid).item() < 1e-6  # a global scale error has no gradient
    flat = _plane(tilt=0.0).log() - target.log()  # the tilted wall predicted face-on
    assert gradient_loss(flat, valid).item() > 0.01


def test_gradient_loss_ignores_holes():
    target = _plane(tilt=1.0)
    g = torch.zeros_like(target)
    g[..., :, 20:] = 0.5  # a jump in the error, hidden by holes on both sides of it
    valid = torch.ones_like(target, dtype=torch.bool)
    assert gradient_loss(g, valid).item() > 0.01
    valid[..., :, 16:24] = False
    assert gradient_loss(g, valid).item() == 0.0


def test_grad_weight_adds_the_term():
    target = _plane(tilt=1.0)
    pred = _plane(tilt=0.0)
    off = depth_loss(pred, target, DepthTrainConfig()).item()
    on = depth_loss(pred, target, DepthTrainConfig(grad_weight=1.0)).item()
    g = pred.log() - target.log()
    expected = gradient_loss(g, torch.ones_like(g, dtype=torch.bool)).item()
    assert abs(on - off - expected) < 1e-5 and expected > 0


def test_photometric_augmentation_changes_colours_not_depth():
    gen = torch.Generator().manual_seed(0)
    rgb = torch.rand(6, 3, 24, 32, generator=gen)
    depth = torch.rand(6, 1, 24, 32, generator=gen) + 1.0
    plain = DepthTrainConfig(min_crop=1.0, flip=False, jitter=0.0)
    x, d = augment(rgb, depth, plain, torch.Generator().manual_seed(1))
    assert torch.equal(x, rgb) and torch.equal(d, depth)
    photo = DepthTrainConfig(min_crop=1.0, flip=False, jitter=0.0, white_balance=0.2, blur=1.5, noise=0.05)
    x1, d1 = augment(rgb, depth, photo, torch.Generator().manual_seed(1))
    x2, _ = augment(rgb, depth, photo, torch.Generator().manual_seed(1))
    assert torch.equal(x1, x2)  # seeded
    assert torch.equal(d1, depth) and x1.shape == rgb.shape
    assert x1.min() >= 0 and x1.max() <= 1 and (x1 - rgb).abs().mean() > 0.01

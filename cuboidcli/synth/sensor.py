"""A Kinect-like depth sensor applied to an exact depth map: noise, quantisation, holes, in-painting.

Every effect is switchable in :class:`SensorOptions`. Each effect draws from its own child generator, so
switching one effect off leaves the random pattern of the others unchanged.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.synth.rays import pixel_directions


@dataclass(frozen=True)
class SensorOptions:
    """Depth sensor model; the defaults imitate a structured-light sensor (Kinect v1, NYU's raw depth)."""

    noise: bool = True
    """Add Gaussian depth noise with sigma = noise_sigma_1m_m * z^2 (z in metres)."""
    noise_sigma_1m_m: float = 0.0015
    """Noise standard deviation at 1 m, metres (1.5 mm; 6 mm at 2 m, 24 mm at 4 m)."""
    quantize_m: float = 0.001
    """Round depths to multiples of this step, metres (the millimetre PNG); 0 keeps them continuous."""
    min_range_m: float = 0.4
    """No return closer than this, metres."""
    max_range_m: float = 10.0
    """No return beyond this, metres."""
    grazing: bool = True
    """Drop returns from surfaces seen at grazing angles."""
    grazing_cos: tuple[float, float] = (0.08, 0.25)
    """|cos| of the incidence angle: always dropped below the first value, never above the second,
    linearly more likely in between."""
    boundary: bool = True
    """Holes at object boundaries: the projector's shadow behind foreground edges, and flickering pixels
    next to depth jumps."""
    baseline_m: float = 0.075
    """Projector-camera baseline, metres (the projector sits to the right of the depth camera)."""
    edge_drop_prob: float = 0.5
    """Probability of dropping a pixel next to a depth jump."""
    dropout: bool = True
    """Random hole blobs (dark, shiny or IR-absorbing patches) and isolated missing pixels."""
    blobs_per_frame: float = 3.0
    """Mean number of hole blobs per frame (Poisson)."""
    blob_radius_px: tuple[float, float] = (2.0, 16.0)
    """Blob semi-axis range in pixels at 640 px image width (scaled with the width)."""
    speckle_rate: float = 0.002
    """Fraction of isolated missing pixels."""
    inpaint: bool = False
    """Fill every hole afterwards (a dense map, like NYU's labelled set)."""

    @classmethod
    def clean(cls) -> SensorOptions:
        """The exact depth map: every effect off (only the range limits remain)."""
        return cls(noise=False, quantize_m=0.0, grazing=False, boundary=False, dropout=False)


def projector_shadow(depth_m: np.ndarray, fx_px: float, baseline_m: float) -> np.ndarray:
    """Pixels the projector (``baseline_m`` to the right of the camera) cannot see: (H, W) bool.

    Pixel u at depth z is shadowed by pixel u' = u + s at depth z' if s < fx * b * (1/z' - 1/z). With
    h(u) = 1/z(u) - u / (fx b) this is h(u') > h(u), so a reverse running maximum of h along each row
    finds every shadowed pixel in one pass.
    """
    valid = depth_m > 0
    inv = np.where(valid, 1.0 / np.where(valid, depth_m, 1.0), -np.inf)
    h = inv - np.arange(depth_m.shape[1]) / (fx_px * baseline_m)
    right_max = np.maximum.accumulate(h[:, ::-1], axis=1)[:, ::-1]
    beyond = np.concatenate([right_max[:, 1:], np.full((h.shape[0], 1), -np.inf)], axis=1)
    return valid & (beyond > h + 1e-4)


def depth_edges(depth_m: np.ndarray, rel_jump: float = 0.03, min_jump_m: float = 0.05) -> np.ndarray:
    """Pixels with a 4-neighbour more than max(min_jump_m, rel_jump * z) away in depth: (H, W) bool."""
    z = depth_m
    edge = np.zeros(z.shape, bool)
    thr = np.maximum(min_jump_m, rel_jump * z)
    for axis in (0, 1):
        d = np.abs(np.diff(z, axis=axis))
        lo = [slice(None), slice(None)]
        hi = [slice(None), slice(None)]
        lo[axis], hi[axis] = slice(0, -1), slice(1, None)
        edge[tuple(lo)] |= d > thr[tuple(lo)]
        edge[tuple(hi)] |= d > thr[tuple(hi)]
    return edge & (z > 0)


def fill_holes(depth_m: np.ndarray) -> np.ndarray:
    """Fill zeros (holes) by push-pull interpolation: average the valid pixels over an image pyramid,
    then fill each level's holes from the smoothly upsampled coarser level. (H, W) float32 -> float32."""
    import cv2

    sums = [(depth_m.astype(np.float64), (depth_m > 0).astype(np.float64))]
    while sums[-1][1].min() == 0 and min(sums[-1][1].shape) > 1:
        v, w = sums[-1]
        hh, ww = (v.shape[0] + 1) // 2 * 2, (v.shape[1] + 1) // 2 * 2
        v = np.pad(v, ((0, hh - v.shape[0]), (0, ww - v.shape[1])))
        w = np.pad(w, ((0, hh - w.shape[0]), (0, ww - w.shape[1])))
        sums.append(
            (v.reshape(hh // 2, 2, ww // 2, 2).sum((1, 3)), w.reshape(hh // 2, 2, ww // 2, 2).sum((1, 3)))
        )
    v, w = sums[-1]
    if not (w > 0).any():
        return np.zeros_like(depth_m, dtype=np.float32)
    filled = np.where(w > 0, v / np.maximum(w, 1e-12), (v.sum() / w.sum()))
    for v, w in reversed(sums[:-1]):
        # the coarser level covers a padded (even) extent; upsample to it, then crop
        hh, ww = (v.shape[0] + 1) // 2 * 2, (v.shape[1] + 1) // 2 * 2
        up = cv2.resize(filled, (ww, hh), interpolation=cv2.INTER_LINEAR)[: v.shape[0], : v.shape[1]]
        filled = np.where(w > 0, v / np.maximum(w, 1e-12), up)
    return filled.astype(np.float32)


def _dropout_mask(shape: tuple[int, int], options: SensorOptions, rng: np.random.Generator) -> np.ndarray:
    import cv2

    h, w = shape
    mask = np.zeros((h, w), np.uint8)
    scale = w / 640.0
    for _ in range(int(rng.poisson(options.blobs_per_frame))):
        cx, cy = rng.uniform(0, w), rng.uniform(0, h)
        ax = rng.uniform(*options.blob_radius_px, size=2) * scale
        angle = rng.uniform(0.0, 180.0)
        cv2.ellipse(mask, (int(cx), int(cy)), (max(1, int(ax[0])), max(1, int(ax[1]))), angle, 0, 360, 1, -1)
    return (mask > 0) | (rng.random((h, w)) < options.speckle_rate)


def simulate_depth(
    depth_m: np.ndarray, normal: np.ndarray, camera: Camera, options: SensorOptions, rng: np.random.Generator
) -> np.ndarray:
    """Apply the sensor model to an exact z-depth map.

    ``depth_m`` (H, W) metres, 0 = no surface; ``normal`` (H, W, 3) camera-frame unit normals; the camera's
    intrinsics scale the ray directions and the projector shadow. Returns (H, W) float32 metres, 0 = hole.
    """
    h, w = depth_m.shape
    child = [np.random.default_rng(s) for s in rng.integers(0, 2**63 - 1, size=4)]
    z = depth_m.astype(np.float64)
    keep = (z >= options.min_range_m) & (z <= options.max_range_m)
    if options.grazing:
        rays = pixel_directions(camera)
        cos = np.abs(np.einsum("hwk,hwk->hw", normal, rays)) / np.sqrt(np.einsum("hwk,hwk->hw", rays, rays))
        lo, hi = options.grazing_cos
        p_drop = np.clip((hi - cos) / (hi - lo), 0.0, 1.0)
        keep &= child[0].random((h, w)) >= p_drop
    if options.boundary:
        # occluders cast shadows whether or not their own return survives
        keep &= ~projector_shadow(z, camera.fx, options.baseline_m)
        keep &= ~(depth_edges(z) & (child[1].random((h, w)) < options.edge_drop_prob))
    if options.dropout:
        keep &= ~_dropout_mask((h, w), options, child[2])
    if options.noise:
        z = z + child[3].normal(size=(h, w)) * options.noise_sigma_1m_m * z * z
    if options.quantize_m > 0:
        z = np.round(z / options.quantize_m) * options.quantize_m
    out = np.where(keep & (z > 0), z, 0.0).astype(np.float32)
    if options.inpaint:
        out = fill_holes(out)
    return out

"""Point splatting: a scan's coloured points drawn into a depth and a colour image from a posed camera,
each point a disc oriented along its surface, the nearest disc winning each pixel; gaps between discs that
a farther surface shows through are emptied and single-pixel holes inside one surface filled. The renderer
of :mod:`.scannet_views`."""

from __future__ import annotations

import numpy as np

from cuboidcli.camera import Camera

#: Points nearer than this (m) to a camera are not drawn: a splat that close would cover the image.
NEAR_M = 0.15
#: The largest splat radius in pixels at 640 pixels of width (scaled with the image): the cameras keep
#: 0.6 m from walls, where a 4 cm disc (a sparse part of a scan) is 35 pixels; a lower cap leaves gaps.
MAX_SPLAT_PX = 40
#: Gaps between discs a farther surface shows through are looked for this far (pixels at 320 wide).
GAP_PX = 4
#: Passes of the hole filling: each closes gaps about one pixel deeper from their rim.
HOLE_PASSES = 2


def splat_radii(points: np.ndarray, cell_m: float = 0.15) -> np.ndarray:
    """(N,) each point's splat radius in metres from the local spacing: a surface through a ``cell_m`` cube
    holds about ``cell_m``² of area, so with ``n`` points in the cube they lie ``cell_m / sqrt(n)`` apart.
    A disc of 0.56 times that would just cover the area if the points were even; a scan's are clustered
    (mesh vertices crowd at edges), so the discs are 1.3 times the spacing: they leave under 1 % of a
    surface of evenly random points uncovered, and those gaps are emptied (:func:`_drop_see_through`)."""
    keys = np.floor(points / cell_m).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    spacing = cell_m / np.sqrt(counts[inverse.ravel()])
    return np.clip(1.3 * spacing, 0.015, 0.08)


def splat_normals(points: np.ndarray, cell_m: float = 0.15) -> np.ndarray:
    """(N, 3) unit normals of the points' splats: the least direction of the points of each ``cell_m`` cell;
    zero where the cell holds too few points or is no plane (a corner, clutter), and such a splat faces the
    camera instead."""
    keys = np.floor(points / cell_m).astype(np.int64)
    _, inverse, counts = np.unique(keys, axis=0, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    mean = np.zeros((len(counts), 3))
    np.add.at(mean, inverse, points)
    mean /= counts[:, None]
    d = points - mean[inverse]
    cov = np.zeros((len(counts), 3, 3))
    np.add.at(cov, inverse, d[:, :, None] * d[:, None, :])
    evals, evecs = np.linalg.eigh(cov)
    planar = (counts >= 6) & (evals[:, 0] <= 0.1 * evals[:, 1])
    normals = np.where(planar[:, None], evecs[:, :, 0], 0.0)
    return normals[inverse]


def to_camera(points: np.ndarray, pose: np.ndarray) -> np.ndarray:
    return (points - pose[:3, 3]) @ pose[:3, :3]


def render_view(
    points: np.ndarray,
    colors: np.ndarray,
    radii: np.ndarray,
    pose: np.ndarray,
    camera: Camera,
    normals: np.ndarray | None = None,
    fill_holes: bool = True,
) -> tuple[np.ndarray, np.ndarray]:
    """(depth (H, W) float metres along the optical axis, 0 = nothing; rgb (H, W, 3) uint8) of the points
    (N, 3) with ``colors`` (N, 3) 0-255, splat ``radii`` (N,) metres and ``normals`` (N, 3) (zero: none),
    seen from camera-to-world ``pose`` with ``camera``: every point a disc of its radius, the nearest disc
    wins each pixel. A disc's depth follows the plane of its normal across its pixels (within its radius
    of the point's depth): a disc at the point's depth throughout would put a slanted surface up to a
    radius nearer the camera, where the nearest-disc rule picks it."""
    w, h = camera.width, camera.height
    pc = to_camera(points, pose)
    z = pc[:, 2]
    front = z > NEAR_M
    uv, z = camera.project(pc[front])
    r_px = np.clip(radii[front] * camera.fx / z, 0.5, MAX_SPLAT_PX * w / 640.0)
    u, v = np.round(uv[:, 0]).astype(np.int64), np.round(uv[:, 1]).astype(np.int64)
    reach = np.ceil(r_px).astype(np.int64)
    near = (u + reach >= 0) & (u - reach < w) & (v + reach >= 0) & (v - reach < h)
    ids = np.flatnonzero(front)[near]
    u, v, z, r_px, reach = u[near], v[near], z[near], r_px[near], reach[near]
    # Each disc's plane in camera axes: n . x = n . p; the zero normals (no plane) give a flat disc.
    n_c = np.zeros((len(ids), 3)) if normals is None else normals[ids] @ pose[:3, :3]
    offset = np.einsum("ij,ij->i", n_c, pc[ids])
    slack = radii[ids]
    pix, depth, owner = [], [], []
    for r in np.unique(reach):
        sel = np.flatnonzero(reach == r)
        dy, dx = np.mgrid[-r : r + 1, -r : r + 1]
        dx, dy = dx.ravel(), dy.ravel()
        # A disc: offsets within the point's own radius (points sharing a ceiling radius differ in it).
        inside = dx[None] ** 2 + dy[None] ** 2 <= r_px[sel, None] ** 2 + 0.25
        uu, vv = u[sel, None] + dx[None], v[sel, None] + dy[None]
        ok = inside & (uu >= 0) & (uu < w) & (vv >= 0) & (vv < h)
        # Where the pixel's ray meets the disc's plane: z n . ((u - cx) / fx, (v - cy) / fy, 1) = n . p.
        n = n_c[sel]
        along = (
            n[:, 0, None] * (uu - camera.cx) / camera.fx
            + n[:, 1, None] * (vv - camera.cy) / camera.fy
            + n[:, 2, None]
        )
        with np.errstate(divide="ignore", invalid="ignore"):
            zz = np.where(np.abs(along) > 1e-6, offset[sel, None] / along, z[sel, None])
        zz = np.clip(
            np.nan_to_num(zz, nan=0.0), z[sel, None] - slack[sel, None], z[sel, None] + slack[sel, None]
        )
        pix.append((vv * w + uu)[ok])
        depth.append(zz[ok])
        owner.append(np.broadcast_to(ids[sel, None], ok.shape)[ok])
    depth_img = np.zeros(h * w)
    rgb = np.zeros((h * w, 3), dtype=np.uint8)
    if pix:
        pix, depth, owner = np.concatenate(pix), np.concatenate(depth), np.concatenate(owner)
        order = np.lexsort((depth, pix))
        first = order[np.r_[True, pix[order][1:] != pix[order][:-1]]]
        depth_img[pix[first]] = depth[first]
        rgb[pix[first]] = colors[owner[first]]
    depth_img, rgb = depth_img.reshape(h, w), rgb.reshape(h, w, 3)
    depth_img, rgb = _drop_see_through(depth_img, rgb, max(2, round(GAP_PX * w / 320)))
    for _ in range(HOLE_PASSES if fill_holes else 0):
        depth_img, rgb = _fill_small_holes(depth_img, rgb)
    return depth_img, rgb


def _drop_see_through(depth: np.ndarray, rgb: np.ndarray, reach: int) -> tuple[np.ndarray, np.ndarray]:
    """Empty the pixels that show a farther surface through a gap between a nearer surface's discs: a
    nearer surface within ``reach`` pixels on both sides, left and right or above and below. A real edge
    has the nearer surface on one side only; a gap between two legs of a chair is emptied too, which only
    loses depth, never gives a wrong one."""
    h, w = depth.shape
    d = np.where(depth > 0, depth, np.inf)
    pad = np.pad(d, reach, constant_values=np.inf)
    tol = 0.1 + 0.05 * depth

    def nearer(dy: int, dx: int) -> np.ndarray:
        steps = [
            pad[reach + k * dy : reach + k * dy + h, reach + k * dx : reach + k * dx + w]
            for k in range(1, reach + 1)
        ]
        return np.min(steps, axis=0) < depth - tol

    through = (depth > 0) & ((nearer(0, -1) & nearer(0, 1)) | (nearer(-1, 0) & nearer(1, 0)))
    depth, rgb = depth.copy(), rgb.copy()
    depth[through] = 0.0
    rgb[through] = 0
    return depth, rgb


def _fill_small_holes(depth: np.ndarray, rgb: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Empty pixels with at least 6 of their 8 neighbours drawn, all within 3 cm + 2 % of each other, take
    the neighbours' mean depth and colour: a gap inside one surface, never a pixel on a depth edge."""
    h, w = depth.shape
    pad = np.pad(depth, 1)
    cpad = np.pad(rgb.astype(np.float64), ((1, 1), (1, 1), (0, 0)))
    shifts = [(dy, dx) for dy in (-1, 0, 1) for dx in (-1, 0, 1) if (dy, dx) != (0, 0)]
    nd = np.stack([pad[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w] for dy, dx in shifts])
    nc = np.stack([cpad[1 + dy : 1 + dy + h, 1 + dx : 1 + dx + w] for dy, dx in shifts])
    valid = nd > 0
    count = valid.sum(0)
    hi = np.where(valid, nd, -np.inf).max(0)
    lo = np.where(valid, nd, np.inf).min(0)
    fill = (depth == 0) & (count >= 6) & (hi - lo <= 0.03 + 0.02 * lo)
    mean = np.where(valid, nd, 0).sum(0) / np.maximum(count, 1)
    cmean = (nc * valid[..., None]).sum(0) / np.maximum(count, 1)[..., None]
    depth, rgb = depth.copy(), rgb.copy()
    depth[fill] = mean[fill]
    rgb[fill] = np.round(cmean[fill]).astype(np.uint8)
    return depth, rgb

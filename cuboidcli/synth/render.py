"""Exact ray casting of triangle meshes into depth, face-id and normal images (open3d RaycastingScene).

One ray per pixel centre (pixel (u, v) looks along ((u - cx) / fx, (v - cy) / fy, 1) in the camera frame,
the convention of :meth:`cuboidcli.camera.Camera.backproject`). Because the ray direction has unit z in the
camera frame, the hit parameter is the z-depth itself. open3d is imported lazily: importing this module
is cheap.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.synth.rays import pixel_directions


@dataclass
class Hits:
    """Result of casting one ray per pixel.

    ``depth_m`` (H, W) float32 z-depth in metres, 0 where the ray hits nothing; ``face`` (H, W) int64
    triangle index, -1 where nothing is hit; ``normal`` (H, W, 3) float32 unit surface normal in the camera
    frame, turned towards the camera (0 where nothing is hit).
    """

    depth_m: np.ndarray
    face: np.ndarray
    normal: np.ndarray

    @property
    def hit(self) -> np.ndarray:
        return self.face >= 0


class RayCaster:
    """A bounding-volume hierarchy over fixed triangles; cast from any camera pose.

    ``vertices`` (V, 3) and ``faces`` (F, 3) are in one frame (the world); a pose maps the camera into it.
    ``threads`` is open3d's thread count (0 = all cores); the hits do not depend on it.
    """

    def __init__(self, vertices: np.ndarray, faces: np.ndarray, threads: int = 0) -> None:
        import open3d as o3d

        self._o3d = o3d
        self._scene = o3d.t.geometry.RaycastingScene()
        self._scene.add_triangles(
            o3d.core.Tensor(np.ascontiguousarray(vertices, dtype=np.float32)),
            o3d.core.Tensor(np.ascontiguousarray(faces, dtype=np.uint32)),
        )
        self.threads = threads

    def cast(
        self,
        camera: Camera,
        rotation: np.ndarray | None = None,
        origin: np.ndarray | None = None,
        step: int = 1,
    ) -> Hits:
        """Render every ``step``-th pixel from the camera at ``origin`` (3,) with camera-to-world
        ``rotation`` (3, 3) (columns: camera x right, y down, z forward in world coordinates).
        Identity pose when both are None (the meshes are already in the camera frame)."""
        rotation = np.eye(3) if rotation is None else np.asarray(rotation, float)
        origin = np.zeros(3) if origin is None else np.asarray(origin, float)
        dirs_cam = pixel_directions(camera, step)
        rays = np.empty(dirs_cam.shape[:2] + (6,), np.float32)
        rays[..., :3] = origin
        # (einsum rather than BLAS for these tall, 3-wide products: no thread start-up, no contention)
        rays[..., 3:] = np.einsum("hwk,ck->hwc", dirs_cam, rotation.astype(np.float32))
        out = self._scene.cast_rays(self._o3d.core.Tensor(rays), nthreads=self.threads)
        t_hit = out["t_hit"].numpy()
        hit = np.isfinite(t_hit)
        face = np.where(hit, out["primitive_ids"].numpy().astype(np.int64), -1)
        # world -> camera: n_c = R^T n_w (for row vectors n_w^T R)
        normal = np.einsum("hwk,kc->hwc", out["primitive_normals"].numpy(), rotation.astype(np.float32))
        # turn normals towards the camera: the ray direction and the normal must point against each other
        facing = np.einsum("hwk,hwk->hw", normal, dirs_cam)
        normal *= np.where(facing > 0, np.float32(-1.0), np.float32(1.0))[..., None]
        normal[~hit] = 0.0
        depth = np.where(hit, t_hit, np.float32(0.0)).astype(np.float32)
        return Hits(depth, face, normal)

    def occluded(self, origins: np.ndarray, directions: np.ndarray) -> np.ndarray:
        """Is anything between each origin (N, 3) and origin + direction (N, 3)? (N,) bool."""
        rays = np.concatenate([origins, directions], -1).astype(np.float32)
        out = self._scene.test_occlusions(
            self._o3d.core.Tensor(np.ascontiguousarray(rays)), tnear=0.0, tfar=1.0, nthreads=self.threads
        )
        return out.numpy().astype(bool)


def cast_boxes(cuboids: list[Cuboid], camera: Camera, step: int = 1) -> tuple[Hits, np.ndarray]:
    """Ray cast cuboids given in the camera frame; returns the hits and the face -> cuboid index map (F,)."""
    from cuboidcli.synth.mesh import box_mesh

    if not cuboids:
        h, w = len(range(0, camera.height, step)), len(range(0, camera.width, step))
        return Hits(
            np.zeros((h, w), np.float32), np.full((h, w), -1, np.int64), np.zeros((h, w, 3), np.float32)
        ), np.zeros(0, np.int64)
    verts, faces = [], []
    for k, c in enumerate(cuboids):
        v, f = box_mesh(c.center, c.half_size, c.rotation)
        verts.append(v)
        faces.append(f + 8 * k)
    owner = np.repeat(np.arange(len(cuboids)), 12)
    return RayCaster(np.concatenate(verts), np.concatenate(faces)).cast(camera, step=step), owner


def render_boxes(
    cuboids: list[Cuboid], camera: Camera, noise: bool = False, seed: int = 0
) -> tuple[np.ndarray, np.ndarray]:
    """Render just the given boxes, exactly, as a depth camera would see them.

    ``cuboids`` are in the OpenCV camera frame (metres). Returns ``depth_m`` (H, W) float32 z-depth in
    metres (0 = no return; without ``noise`` there is no range limit either) and ``instance`` (H, W)
    int32: 1 + the index of the visible cuboid, 0 for none. With ``noise`` the default sensor model of
    :class:`cuboidcli.synth.sensor.SensorOptions` (noise, millimetre quantisation, holes, 0.4-10 m range)
    is applied with a generator seeded by ``seed``; ``instance`` is then still the noise-free visibility.
    """
    hits, owner = cast_boxes(cuboids, camera)
    instance = np.where(hits.hit, owner[np.maximum(hits.face, 0)] + 1, 0).astype(np.int32)
    depth = hits.depth_m
    if noise:
        from cuboidcli.synth.sensor import SensorOptions, simulate_depth

        depth = simulate_depth(depth, hits.normal, camera, SensorOptions(), np.random.default_rng(seed))
    return depth, instance

"""The Python API: cuboids from a depth map in a notebook or a pipeline, without the command line.

    import cuboidcli as cb

    camera = cb.Camera(fx=518.86, fy=519.47, cx=325.58, cy=253.74)   # pixels; size from the depth map
    depth_m = cb.read_depth("frame_depth.png", depth_scale=0.001)      # (H, W) float32, metres, 0 = missing
    result = cb.fit(depth_m, camera, seed=0)
    for box in result.cuboids:                                          # cuboidcli.Cuboid, OpenCV frame
        print(box.center, 2 * box.half_size)

    fitter = cb.Fitter(sampler="learned")   # weights loaded and kernels compiled once ...
    results = [fitter.fit(d, camera) for d in depth_maps]               # ... reused for every frame

``cuboids fit`` runs the same :class:`Fitter`; settings and defaults are those of
:class:`~cuboidcli.fitting.config.FitConfig` (which are the command's defaults). The library never imports
the command-line packages (typer, rich).
"""

from __future__ import annotations

import dataclasses
import os
from dataclasses import dataclass, replace
from functools import cached_property
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid
from cuboidcli.fitting.config import FitConfig, resolve_device
from cuboidcli.fitting.parts import SAMPLERS as SAMPLERS  # the names the estimator accepts, registered
from cuboidcli.fitting.parts import SOLVERS as SOLVERS  # in cuboidcli.fitting.parts
from cuboidcli.io.depth import read_camera as read_camera  # cb.read_camera
from cuboidcli.io.result import FitResult, frame_result, input_record

#: FitConfig fields a caller may set by keyword (``cb.fit(..., hypotheses=1024)``); device is separate.
SETTINGS = tuple(f.name for f in dataclasses.fields(FitConfig) if f.name != "device")


@dataclass(repr=False)
class Result:
    """One fitted frame: the cuboids, how they were found, and the outputs made from them.

    ``record`` is the "cuboids/1" content (what ``cuboids fit`` writes), ``info`` what happened while fitting
    (per-cuboid gains, Theta, steps, stop reason, per-stage seconds), ``depth_m`` (H, W) the depth map that
    was fitted and ``rgb`` (H, W, 3) uint8 the image, if one was given.
    """

    record: FitResult
    info: object
    """:class:`cuboidcli.fitting.pipeline.FitInfo`."""
    depth_m: np.ndarray
    rgb: np.ndarray | None = None

    @property
    def cuboids(self) -> list[Cuboid]:
        """The cuboids in selection order, OpenCV camera frame, metres (each with its ``inlier_gain``)."""
        return self.record.cuboids

    @property
    def camera(self) -> Camera:
        return self.record.camera

    @property
    def settings(self) -> dict:
        """The resolved configuration (FitConfig fields, Theta used, solver, sampler, weights)."""
        return self.record.settings

    @property
    def grid_labels(self) -> np.ndarray:
        """(ceil(H / s), ceil(W / s)) int32 over the fitting grid (step s = ``info.grid_step``), as counted
        while fitting: k >= 0 inlier of cuboid k, -1 none, -2 hidden behind a cuboid, -3 no depth."""
        return self.info.assignment

    @cached_property
    def labels(self) -> np.ndarray:
        """(H, W) int32 per pixel: k >= 0 inlier of cuboid k, -1 none, -2 hidden behind a cuboid, -3 no
        depth. Every pixel's point is assigned with the fit's own tau, beta and occlusion setting."""
        from cuboidcli.export.ply import assign_labels, depth_points

        h, w = self.depth_m.shape
        labels = np.full(h * w, -3, dtype=np.int32)
        points, pix = depth_points(self.depth_m, self.camera)
        labels[pix] = assign_labels(points, self.cuboids, self.settings)
        return labels.reshape(h, w)

    def to_json(self) -> dict:
        """The "cuboids/1" document (README, "Output schema")."""
        return self.record.to_json()

    def save_json(self, path: str | os.PathLike) -> Path:
        """Write the "cuboids/1" JSON, atomically."""
        from cuboidcli.io.result import write_result

        return write_result(path, self.record)

    def save_glb(self, path: str | os.PathLike, *, with_points: bool = False) -> Path:
        """GLB (glTF axes) with one node per cuboid; ``with_points`` adds the depth map's point cloud,
        coloured from the RGB image if there is one, else by cuboid."""
        from cuboidcli.export import write_result_glb

        return write_result_glb(
            self.record, path, depth_m=self.depth_m, rgb=self.rgb, with_points=with_points
        )

    def save_ply(
        self, points_path: str | os.PathLike, cuboids_path: str | os.PathLike | None = None
    ) -> dict[str, Path]:
        """The point cloud coloured by cuboid (``points_path``) and the cuboid meshes (``cuboids_path``,
        default ``<name>_cuboids.ply`` beside it), OpenCV frame. Returns {"points_ply", "cuboids_ply"}."""
        from cuboidcli.export import write_result_ply

        return write_result_ply(self.record, points_path, self.depth_m, cuboids_path=cuboids_path)

    def overlay(self, rgb: np.ndarray | None = None) -> np.ndarray:
        """(H, W, 3) uint8: the cuboids drawn over ``rgb`` (default: the frame's image, else its coloured
        depth), z-buffered against each other."""
        from cuboidcli.export.overlay import background_image, draw_overlay

        rgb = self.rgb if rgb is None else rgb
        background = background_image(self.camera, rgb, None if rgb is not None else self.depth_m)
        return draw_overlay(background, self.camera, self.cuboids)

    def save(
        self,
        json_path: str | os.PathLike,
        *,
        glb: bool = False,
        ply: bool = False,
        overlay: bool = False,
        with_points: bool = False,
        scenes: tuple[str, ...] = (),
    ) -> list[Path]:
        """The JSON and, beside it, the outputs ``cuboids fit`` writes with --glb, --ply, --overlay and the
        scene files of ``scenes`` (kinds of :data:`cuboidcli.export.SCENES`: ``"html"``, ...).

        The JSON is written last (each file atomically): where it exists, the frame's outputs are complete.
        Returns the paths, the JSON first."""
        written = []
        if glb or ply or overlay or scenes:
            from cuboidcli.export import write_outputs

            stem = Path(json_path).with_name(Path(json_path).name.removesuffix(".json"))
            paths = write_outputs(
                self.record,
                stem,
                depth_m=self.depth_m,
                rgb=self.rgb,
                glb=glb,
                ply=ply,
                overlay=overlay,
                with_points=with_points,
                scenes=tuple(scenes),
            )
            written += list(paths.values())
        return [self.save_json(json_path), *written]

    def __repr__(self) -> str:
        return (
            f"Result({len(self.cuboids)} cuboids, {self.info.n_points} points, "
            f"stop: {self.info.stop_reason}, {self.info.timing_s.get('total', 0.0):.2f} s)"
        )


class Fitter:
    """The estimator, built once: weights loaded, CPU kernels compiled. :meth:`fit` then fits frame after
    frame; each call is deterministic for its seed and independent of the calls before it.

    ``config``: a FitConfig to start from (default: the defaults of ``cuboids fit``); keyword ``settings``
    override its fields (``sampler``, ``solver``, ``hypotheses``, ``max_cuboids``, ``seed``, ``theta``,
    ``grid_step``, ``local_fraction``, ``max_batches``, ``refine``, ...). ``weights``: a folder or .pt file
    of network weights (default: the shipped ones that go with the solver); ``onnx``: the exported solver
    for ``solver="onnx"``; ``device``: auto, cpu or cuda. Raises ValueError for bad settings,
    FileNotFoundError for missing weights.
    """

    def __init__(
        self,
        config: FitConfig | None = None,
        *,
        weights: str | os.PathLike | None = None,
        onnx: str | os.PathLike | None = None,
        device: str = "auto",
        **settings,
    ) -> None:
        from cuboidcli.factories import make_sampler, make_solver
        from cuboidcli.fitting.pipeline import ensure_compiled
        from cuboidcli.weights import default_weights_dir, shipped_path

        unknown = sorted(set(settings) - set(SETTINGS))
        if unknown:
            raise TypeError(f"unknown setting {unknown[0]!r}; settings are the FitConfig fields: {SETTINGS}")
        self.config = replace(config or FitConfig(), **settings, device=resolve_device(device))
        self.config.check()
        # No weights given: the shipped bundle that matches the solver.
        self.weights = default_weights_dir(self.config.solver) if weights is None else shipped_path(weights)
        self.onnx = None if onnx is None else Path(onnx)
        self.solver = make_solver(self.config, self.weights, self.onnx, self.config.device)
        self.sampler = make_sampler(self.config.sampler, self.weights, self.config.device, self.config)
        if self.config.device == "cpu":
            ensure_compiled(self.solver, self.sampler)

    def fit(
        self,
        depth_m: np.ndarray,
        camera: Camera,
        *,
        rgb: np.ndarray | None = None,
        seed: int | None = None,
        progress=None,
    ) -> Result:
        """Fit a depth map (H, W) in metres (0, NaN, inf = missing) seen by ``camera`` (pixels; a width and
        height of 0 take the depth map's). ``rgb`` (H, W, 3) uint8 only colours the outputs. ``seed``
        overrides the configured one. ``progress(step, cuboids, gain)`` is called after every step.
        Raises ValueError for unusable input (no valid depth, a unit that looks wrong, mismatched sizes)."""
        from cuboidcli.io.depth import check_inputs, warn_all

        depth_m = np.asarray(depth_m)
        if depth_m.ndim != 2 or not np.issubdtype(depth_m.dtype, np.number):
            raise ValueError(f"depth_m must be a 2-D array of metres, got {depth_m.shape} {depth_m.dtype}")
        depth_m = np.where(valid_depth(depth_m), depth_m, 0.0).astype(np.float32)
        h, w = depth_m.shape
        camera = camera.for_image(w, h)
        warn_all(check_inputs(depth_m, camera, None if rgb is None else np.shape(rgb)))
        meta = input_record(
            depth_m, depth=None, image=None, depth_source="array", depth_scale=None, intrinsics_source="api"
        )
        return self._fit(depth_m, camera, rgb, meta, None, seed, progress)

    def fit_photo(
        self,
        path: str | os.PathLike,
        *,
        intrinsics: str | None = None,
        preset: str | None = None,
        depth_model: str | None = None,
        camera_height_m: float | None = None,
        progress=None,
    ) -> Result:
        """Fit a photo as ``cuboids fit photo.jpg`` does: upright after its EXIF orientation, the camera
        from ``intrinsics`` (``"fx,fy,cx,cy"`` or a JSON file) or ``preset``, else its EXIF, the depth
        model or a 63 degree field of view (a warning), the depth from ``depth_model`` (None: the built-in
        network; ``"hf:owner/name"``, a folder saved with save_pretrained, an .onnx or .pt file), which is
        loaded once per process. ``camera_height_m`` scales a relative model. Raises ValueError for
        unusable input; warnings (:class:`cuboidcli.io.depth.InputWarning`) for what the user should know."""
        from cuboidcli.factories import DepthModelOptions
        from cuboidcli.frame import load_frame
        from cuboidcli.io.depth import warn_all
        from cuboidcli.weights import depth_model_path

        model = depth_model_path(depth_model)
        opts = DepthModelOptions(model, device=self.config.device, camera_height_m=camera_height_m)
        frame = load_frame(None, path, intrinsics, preset, depth_model=opts)
        warn_all(frame.notes)
        return self.fit_frame(frame, progress=progress)

    def fit_frame(self, frame, *, progress=None) -> Result:
        """Fit a frame read by :func:`cuboidcli.frame.load_frame` (what ``cuboids fit`` does); its
        file names and, for RGB input, the depth estimation time go into the result."""
        f = frame
        return self._fit(f.depth_m, f.camera, f.rgb, f.meta, f.depth_seconds, None, progress)

    def _fit(self, depth_m, camera, rgb, meta, depth_seconds, seed, progress) -> Result:
        from cuboidcli.fitting.pipeline import fit_depth

        config = self.config if seed is None else replace(self.config, seed=int(seed))
        cuboids, info = fit_depth(
            depth_m, camera, config, solver=self.solver, sampler=self.sampler, progress=progress
        )
        if depth_seconds is not None:
            info.add_depth_time(depth_seconds)
        record = frame_result(
            camera, cuboids, info, config, meta, self.solver.name, self.sampler.name, self._files()
        )
        return Result(record, info, depth_m, rgb)

    def fit_scene(
        self,
        path: str | os.PathLike,
        *,
        scene=None,
        unit: str = "m",
        every: int = 1,
        intrinsics: str | None = None,
        depth_scale: float | None = None,
        progress=None,
        fuse_progress=None,
    ):
        """Fit a whole room as ``cuboids fit room.ply`` (or a sequence folder) does: a point cloud or mesh
        file (.ply, .pcd, .obj, .glb/.gltf, .npy/.npz; ``unit`` m, cm or mm) or a posed RGB-D sequence
        folder (TUM, ScanNet, Redwood or the plain layout; every ``every``-th frame, fused), fitted in the
        input's own frame. ``scene``: a :class:`cuboidcli.fitting.scene.SceneConfig` (voxel, fitting
        points, ``max_cuboids`` (40), visibility, up). Returns a :class:`cuboidcli.scene.SceneResult`.
        Raises ValueError (:class:`cuboidcli.io.depth.InputError`) for unusable input."""
        from cuboidcli.fitting.scene import SceneConfig, fit_scene
        from cuboidcli.scene import SceneResult, load_scene, scene_result

        scene = scene or SceneConfig()
        data = load_scene(
            path,
            unit=unit,
            every=every,
            intrinsics=intrinsics,
            depth_scale=depth_scale,
            progress=fuse_progress,
        )
        cloud = data.cloud
        cuboids, info = fit_scene(
            cloud.points, self.config, scene, solver=self.solver, sampler=self.sampler,
            viewpoints=cloud.viewpoints, up_hint=data.up_hint, progress=progress,
        )  # fmt: skip
        info.fit.timing_s = {"load": round(data.load_seconds, 6), **info.timing_s}
        record = scene_result(
            data, cuboids, info, self.config, scene, self.solver.name, self.sampler.name, path, self._files()
        )
        record.timing_s = info.fit.timing_s
        return SceneResult(record, info, data)

    def _files(self) -> dict:
        """The weights and ONNX files a result records."""
        return {"weights": _str_or_none(self.weights), "onnx": _str_or_none(self.onnx)}


def fit(
    depth_m: np.ndarray,
    camera: Camera,
    *,
    rgb: np.ndarray | None = None,
    weights: str | os.PathLike | None = None,
    onnx: str | os.PathLike | None = None,
    device: str = "auto",
    progress=None,
    **settings,
) -> Result:
    """Fit one depth map: ``Fitter(**settings).fit(depth_m, camera)``. For many frames build a
    :class:`Fitter` once instead. Settings and defaults as :class:`Fitter` (those of ``cuboids fit``)."""
    fitter = Fitter(weights=weights, onnx=onnx, device=device, **settings)
    return fitter.fit(depth_m, camera, rgb=rgb, progress=progress)


def _str_or_none(p) -> str | None:
    return None if p is None else str(p)


def read_depth(path: str | os.PathLike, depth_scale: float = 0.001) -> np.ndarray:
    """A depth map (H, W) float32 in metres, 0 = missing: 16-bit PNG (``depth_scale`` metres per unit;
    TUM: 1/5000), .npy/.npz in metres, .exr in metres. Raises ValueError for unusable files."""
    from cuboidcli.io.depth import read_depth as _read

    if depth_scale <= 0:
        raise ValueError(f"depth_scale must be positive (got {depth_scale})")
    return _read(path, depth_scale)


def read_rgb(path: str | os.PathLike) -> np.ndarray:
    """A colour image (H, W, 3) uint8 RGB."""
    from cuboidcli.io.depth import read_rgb as _read

    return _read(path)


def estimate_depth(
    rgb: np.ndarray, camera: Camera, *, model: str | os.PathLike | None = None, device: str = "auto"
) -> np.ndarray:
    """Metric depth (H, W) float32 in metres predicted from an RGB image (H, W, 3) uint8 by the built-in
    network (``model`` None: the shipped weights; a .pt checkpoint of it; or a metric ONNX model). The
    network is loaded once per process."""
    from cuboidcli.depth import estimate_depth as _estimate
    from cuboidcli.factories import DepthModelOptions, depth_estimator
    from cuboidcli.weights import depth_model_path

    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"rgb must be an (H, W, 3) image, got shape {rgb.shape}")
    h, w = rgb.shape[:2]
    estimator = depth_estimator(DepthModelOptions(depth_model_path(model), device=resolve_device(device)))
    depth, _ = _estimate(estimator, rgb, camera.for_image(w, h))
    return depth

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
from dataclasses import replace
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.fitting.checks import LOAD_CHECKS, check_all
from cuboidcli.fitting.config import CHECKS, FitConfig, resolve_device
from cuboidcli.fitting.parts import SAMPLERS as SAMPLERS  # the names the estimator accepts, registered
from cuboidcli.fitting.parts import SOLVERS as SOLVERS  # in cuboidcli.fitting.parts
from cuboidcli.io.depth import read_camera as read_camera  # cb.read_camera
from cuboidcli.load import Input, LoadOptions
from cuboidcli.result import Result as Result  # where 0.2.0 users import it from

#: FitConfig fields a caller may set by keyword (``cb.fit(..., hypotheses=1024)``); device is separate.
SETTINGS = tuple(f.name for f in dataclasses.fields(FitConfig) if f.name != "device")


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
        x,
        camera: Camera | None = None,
        *,
        rgb: np.ndarray | None = None,
        image: str | os.PathLike | None = None,
        options: LoadOptions | None = None,
        seed: int | None = None,
        progress=None,
        fuse_progress=None,
        **load,
    ) -> Result:
        """Fit one input, as ``cuboids fit`` does:

        - a depth map (H, W) in metres (0, NaN, inf = missing) seen by ``camera`` (pixels; a width and
          height of 0 take the depth map's); ``rgb`` (H, W, 3) uint8 only colours the outputs;
        - a depth map file (``image``: its photo) or a photo (depth from RGB, the camera from ``-K``,
          ``--camera``, EXIF, the depth model or a default field of view), fitted in the camera's frame;
        - a scan file (.ply .pcd .obj .glb/.gltf .npy/.npz), a posed RGB-D sequence folder, points (N, 3)
          metres or (N, 6) with colours 0-255, or an Open3D point cloud: a room, fitted in its own frame.

        How to read it: ``options`` (:class:`~cuboidcli.load.LoadOptions`) or its fields as keywords
        (``intrinsics``, ``camera_preset`` for ``--camera``, ``depth_scale``, ``unit``, ``every``,
        ``depth_model``). ``seed`` overrides the configured one. ``progress(step, cuboids, gain)`` is called
        after every step, ``fuse_progress(done, total)`` after each frame of a sequence. Raises ValueError
        (:class:`~cuboidcli.io.depth.InputError`) for unusable input; warnings
        (:class:`~cuboidcli.io.depth.InputWarning`) for what the user should know."""
        from cuboidcli.io.depth import warn_all
        from cuboidcli.load import load as load_input

        if "camera_preset" in load:
            load["camera"] = load.pop("camera_preset")
        if options is not None and load:
            raise TypeError("give the loading options either as options= or as keywords, not both")
        options = options or LoadOptions(**load)
        _check_load(options)
        if seed is not None:
            check_all(CHECKS, {"seed": seed})
        options = self._depth_model(options, x, camera)
        inp = load_input(x, options, camera=camera, image=image, rgb=rgb, progress=fuse_progress)
        warn_all(inp.notes)
        return self.fit_input(inp, options, seed=seed, progress=progress)

    def _depth_model(self, options: LoadOptions, x, camera: Camera | None) -> LoadOptions:
        """``options`` with a photo's depth model as the command line sets it: a model given by name (a
        path, ``hf:owner/name``) made options, and the built-in one for a photo given none; either runs on
        the Fitter's device."""
        from cuboidcli.factories import DepthModelOptions
        from cuboidcli.load import source_of
        from cuboidcli.weights import depth_model_path

        model = options.depth_model
        if isinstance(model, str | os.PathLike):
            model = DepthModelOptions(depth_model_path(model), device=self.config.device)
        elif model is None and not isinstance(x, np.ndarray) and source_of(x, camera) == "photo":
            model = DepthModelOptions(device=self.config.device)
        return replace(options, depth_model=model)

    def fit_input(
        self, inp: Input, options: LoadOptions | None = None, *, seed: int | None = None, progress=None
    ) -> Result:
        """Fit an input read by :func:`cuboidcli.load.load` with ``options`` (what a folder's job does):
        the settings for its kind (a room's defaults where a setting was left unset), the estimator, the
        "cuboids/1" record."""
        from cuboidcli.fitting.pipeline import estimate, warm_up_room
        from cuboidcli.result import Result, result_record

        config = self.config.for_kind(inp.kind)
        if seed is not None:
            config = replace(config, seed=int(seed))  # checked by fit(); a numpy integer made one for JSON
        if inp.kind == "room":
            warm_up_room(self.solver, self.sampler)
        fit_in = inp.fit_input(config)
        cuboids, info = estimate(fit_in, config, solver=self.solver, sampler=self.sampler, progress=progress)
        if inp.lines_seconds is not None:  # the photo's lines, found at load time: stage "lines"
            info.timing_s = {"lines": round(inp.lines_seconds, 6), **info.timing_s}
            info.timing_s["total"] = round(info.timing_s.get("total", 0.0) + inp.lines_seconds, 6)
        if inp.depth_seconds is not None:  # listed first
            info.add_depth_time(inp.depth_seconds)
        extra = {**self._files(), "load": (options or LoadOptions()).to_dict(inp.source)}
        record = result_record(inp, cuboids, info, config, self.solver.name, self.sampler.name, extra)
        return Result(record, info, inp)

    def _files(self) -> dict:
        """The weights and ONNX files a result records."""
        return {"weights": _str_or_none(self.weights), "onnx": _str_or_none(self.onnx)}


def fit(
    x,
    camera: Camera | None = None,
    *,
    rgb: np.ndarray | None = None,
    weights: str | os.PathLike | None = None,
    onnx: str | os.PathLike | None = None,
    device: str = "auto",
    progress=None,
    **settings,
) -> Result:
    """Fit one input (a depth map with its camera, a file, a folder, points: :meth:`Fitter.fit`):
    ``Fitter(**settings).fit(x, camera)``. For many inputs build a :class:`Fitter` once instead. Settings
    and defaults as :class:`Fitter` (those of ``cuboids fit``)."""
    fitter = Fitter(weights=weights, onnx=onnx, device=device, **settings)
    return fitter.fit(x, camera, rgb=rgb, progress=progress)


def _check_load(options: LoadOptions) -> None:
    """The checks of how an input is read (:data:`~cuboidcli.fitting.checks.LOAD_CHECKS`), a depth model's
    scale, shift, camera height and kind among them: a one-line ValueError, as the command line's."""
    values = {f.name: getattr(options, f.name) for f in dataclasses.fields(options)}
    model = values.pop("depth_model")
    if model is not None and not isinstance(model, str | os.PathLike):
        values.update({name: getattr(model, name) for name in ("kind", "scale", "shift", "camera_height_m")})
    check_all(LOAD_CHECKS, values)


def _str_or_none(p) -> str | None:
    return None if p is None else str(p)


def read_depth(path: str | os.PathLike, depth_scale: float = 0.001) -> np.ndarray:
    """A depth map (H, W) float32 in metres, 0 = missing: 16-bit PNG (``depth_scale`` metres per unit;
    TUM: 1/5000), .npy/.npz in metres, .exr in metres. Raises ValueError for unusable files."""
    from cuboidcli.io.depth import read_depth as _read

    check_all(LOAD_CHECKS, {"depth_scale": depth_scale})
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
    from cuboidcli.factories import DepthModelOptions
    from cuboidcli.load.frame import depth_from_rgb
    from cuboidcli.weights import depth_model_path

    rgb = np.asarray(rgb)
    if rgb.ndim != 3 or rgb.shape[2] != 3:
        raise ValueError(f"rgb must be an (H, W, 3) image, got shape {rgb.shape}")
    h, w = rgb.shape[:2]
    opts = DepthModelOptions(depth_model_path(model), device=resolve_device(device))
    return depth_from_rgb(rgb, camera.for_image(w, h), opts).depth_m

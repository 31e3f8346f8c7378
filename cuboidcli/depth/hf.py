"""Hugging Face ``transformers`` depth-estimation models as depth estimators (``pip install 'cuboids[hf]'``).

``--depth-model`` names one as a local folder written by ``save_pretrained`` (it holds ``config.json`` and
``preprocessor_config.json``) or as ``hf:owner/name``, a model id downloaded on first use into the
standard Hugging Face cache (``huggingface_hub.constants.HF_HUB_CACHE``; ``HF_HUB_OFFLINE=1`` uses the
cache only). The model's own image processor prepares the image (its input size, resizing and
normalisation) and its ``post_process_depth_estimation`` resizes the prediction to the full image.

What each architecture predicts, from its config (override with ``kind`` where it makes sense):

============== ===================================================== ====================================
model_type     output                                                kinds accepted
============== ===================================================== ====================================
depth_anything ``depth_estimation_type`` "relative": affine-invariant relative-inverse (default) if relative;
               inverse depth; "metric": metres                       metric (default) or relative if metric
dpt            MiDaS-style relative inverse depth; NYU/KITTI         relative-inverse (default), metric,
               fine-tunes predict metres but their config does not   relative
               say so: pass kind metric for those
zoedepth       metres                                                metric (default), relative
glpn           metres                                                metric (default), relative
depth_pro      metres, and the horizontal field of view              metric (default), relative
============== ===================================================== ====================================

``transformers`` is imported only when such a model is used.
"""

from __future__ import annotations

import math
import os
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.depth.image import check_rgb
from cuboidcli.depth.scale import DepthScaling

HF_PREFIX = "hf:"
#: The files save_pretrained writes a model's weights to: one of them, or the index of its shards.
WEIGHT_FILES = (
    "model.safetensors", "model.safetensors.index.json", "pytorch_model.bin", "pytorch_model.bin.index.json",
)  # fmt: skip
EXTRA_HINT = "pip install 'cuboids[hf]'"

#: model_type -> (the kind it predicts, None: read from the config; the kinds a user may ask for).
ARCHITECTURES: dict[str, tuple[str | None, tuple[str, ...]]] = {
    "depth_anything": (None, ()),
    "dpt": ("relative-inverse", ("relative-inverse", "metric", "relative")),
    "zoedepth": ("metric", ("metric", "relative")),
    "glpn": ("metric", ("metric", "relative")),
    "depth_pro": ("metric", ("metric", "relative")),
}


def is_hf_model(model: str | os.PathLike | None) -> bool:
    """Whether a ``--depth-model`` value names a Hugging Face model: ``hf:owner/name`` or a folder."""
    if model is None:
        return False
    return str(model).startswith(HF_PREFIX) or Path(model).is_dir()


def _transformers():
    try:
        import transformers
    except ImportError as e:
        raise ImportError(f"a Hugging Face depth model needs the optional extra: {EXTRA_HINT}") from e
    return transformers


def native_kind(config) -> tuple[str, tuple[str, ...]]:
    """(the kind the model's config says it predicts, the kinds a user may ask for instead)."""
    kind, allowed = ARCHITECTURES[config.model_type]
    if config.model_type == "depth_anything":
        if getattr(config, "depth_estimation_type", "relative") == "metric":
            return "metric", ("metric", "relative")
        return "relative-inverse", ("relative-inverse",)
    return kind, allowed


class HFDepthEstimator:
    """A ``transformers`` depth-estimation model (Depth Anything V1/V2, DPT, ZoeDepth, GLPN, Depth Pro).

    ``model``: a folder written by ``save_pretrained`` or ``hf:owner/name``. ``kind``: None = what the
    config says (:data:`ARCHITECTURES`); relative kinds need a scale source (:class:`DepthScaling`).
    ``device``: "cpu" or "cuda". Loading errors are one-line ValueErrors (ImportError without
    ``transformers``).

    ``predicts_focal`` is True for a Depth Pro model with its field-of-view head: ``predict_with_focal``
    then gives depth for an unknown camera together with the focal length it assumed.
    """

    def __init__(
        self,
        model: str | os.PathLike,
        kind: str | None = None,
        scale: float | None = None,
        shift: float | None = None,
        ref_depth: np.ndarray | None = None,
        camera_height_m: float | None = None,
        device: str = "cpu",
    ) -> None:
        text = str(model)
        self.repo_id = text[len(HF_PREFIX) :] if text.startswith(HF_PREFIX) else None
        self.source = self.repo_id if self.repo_id is not None else str(Path(model))
        self.name = text if self.repo_id is not None else Path(model).name
        if self.repo_id is not None and (not self.repo_id or self.repo_id.count("/") > 1):
            raise ValueError(f"depth model {text}: expected hf:owner/name (a Hugging Face model id)")
        if self.repo_id is None and not (Path(model) / "config.json").is_file():
            raise ValueError(
                f"depth model folder {model} has no config.json: expected a Hugging Face model saved with "
                "save_pretrained (or a .pt / .onnx file)"
            )
        if self.repo_id is None and not any((Path(model) / name).is_file() for name in WEIGHT_FILES):
            raise ValueError(
                f"depth model folder {model} has a config.json but no weights ({', '.join(WEIGHT_FILES)}): "
                "save the model itself with save_pretrained, not only its config"
            )
        transformers = _transformers()
        config = self._load(transformers.AutoConfig)
        model_type = getattr(config, "model_type", None)
        if model_type not in ARCHITECTURES:
            archs = ", ".join(getattr(config, "architectures", None) or []) or "no architectures listed"
            raise ValueError(
                f"depth model {self.name} is a {model_type} model ({archs}), not a supported "
                f"depth-estimation model; supported: {', '.join(ARCHITECTURES)}"
            )
        self.model_type = model_type
        self.native_kind, allowed = native_kind(config)
        kind = kind or self.native_kind
        if kind not in allowed:
            raise ValueError(
                f"depth model {self.name} ({model_type}) predicts {self.native_kind} depth; "
                f"kind {kind!r} does not apply (choose {' or '.join(allowed)})"
            )
        self.scaling = DepthScaling(kind, scale, shift, ref_depth, camera_height_m)
        self.predicts_focal = model_type == "depth_pro" and bool(getattr(config, "use_fov_model", False))
        self.processor = self._load_processor(transformers)
        import torch

        self.device = torch.device(device)
        # transformers draws a bar while it copies the weights into the model (not the download's): noise
        # between our own lines, and a second of work at most
        bars = transformers.utils.logging.is_progress_bar_enabled()
        transformers.utils.logging.disable_progress_bar()
        try:
            net, info = self._load(transformers.AutoModelForDepthEstimation, output_loading_info=True)
        finally:
            if bars:
                transformers.utils.logging.enable_progress_bar()
        missing = sorted(info.get("missing_keys") or ())
        if missing:  # transformers would start them at random and only log a table of their names
            raise ValueError(
                f"depth model {self.name}: its weights lack {len(missing)} of the model's parameters "
                f"({missing[0]}, ...), which would start random; save the whole model with save_pretrained"
            )
        self.net = net.to(self.device).eval()

    # --- loading -----------------------------------------------------------------------------------------

    def _load(self, auto_class, **kwargs):
        """``auto_class.from_pretrained(source, **kwargs)`` with the user-facing one-line errors."""
        import logging

        # Without a network huggingface_hub logs every retry (five, over ~25 s) before it gives up; the
        # user gets our one line instead. Its download progress bars are not log records and still show.
        # transformers' own report of missing weights is replaced by ours (__init__).
        logs = [logging.getLogger(name) for name in ("huggingface_hub", "transformers")]
        levels = [log.level for log in logs]
        for log, level in zip(logs, levels, strict=True):
            log.setLevel(max(level, logging.ERROR))
        try:
            return auto_class.from_pretrained(self.source, **kwargs)
        except (OSError, ValueError, KeyError) as e:
            raise ValueError(self._load_error(e)) from e
        finally:
            for log, level in zip(logs, levels, strict=True):
                log.setLevel(level)

    def _load_error(self, e: Exception) -> str:
        first = (str(e).strip().splitlines() or [type(e).__name__])[0]
        if self.repo_id is None:
            return f"cannot load the Hugging Face model in {self.source}: {first}"
        from huggingface_hub import constants

        offline = " (HF_HUB_OFFLINE is set: cache only)" if constants.HF_HUB_OFFLINE else ""
        return (
            f"Hugging Face model {self.repo_id} is not in the cache {constants.HF_HUB_CACHE} and could "
            f"not be downloaded{offline}: run once with a network connection (and without HF_HUB_OFFLINE=1) "
            "to download it, or check the model id"
        )

    def _load_processor(self, transformers):
        try:
            return transformers.AutoImageProcessor.from_pretrained(self.source)
        except (ImportError, OSError, ValueError, KeyError) as e:
            first = (str(e).strip().splitlines() or [type(e).__name__])[0]
            if "torchvision" in str(e):
                # transformers has Depth Pro's processor for the torchvision backend only
                if self.model_type == "depth_pro":
                    return _DepthProPlainProcessor(self._processor_dict())
                raise ValueError(
                    f"depth model {self.name}: its image processor needs torchvision ({first})"
                ) from e
            if isinstance(e, ImportError):
                raise ImportError(f"depth model {self.name}: {first}") from e
            if self.repo_id is not None:
                raise ValueError(self._load_error(e)) from e
            raise ValueError(
                f"depth model folder {self.source} has no usable image processor (preprocessor_config.json); "
                "save it with the model's processor.save_pretrained"
            ) from e

    def _processor_dict(self) -> dict:
        from transformers.image_processing_utils import ImageProcessingMixin

        try:
            return ImageProcessingMixin.get_image_processor_dict(self.source)[0]
        except (OSError, ValueError) as e:
            raise ValueError(self._load_error(e)) from e

    # --- prediction --------------------------------------------------------------------------------------

    @property
    def kind(self) -> str:
        return self.scaling.kind

    def _forward(self, rgb: np.ndarray):
        import torch

        inputs = self.processor(images=rgb, return_tensors="pt")
        inputs = {k: v.to(self.device) for k, v in inputs.items() if isinstance(v, torch.Tensor)}
        with torch.inference_mode():
            return self.net(**inputs)

    def raw_output(self, rgb: np.ndarray, camera: Camera) -> np.ndarray:
        """The model's post-processed prediction at the image's resolution (H, W) float64, before scaling:
        metres for metric models, relative (inverse) depth otherwise."""
        check_rgb(rgb, camera)
        out = self._forward(rgb)
        if self.model_type == "depth_pro":
            return self._depth_pro_depth(out, rgb.shape[:2], camera.fx)
        return self._post_process(out, rgb.shape[:2])

    def _post_process(self, out, hw: tuple[int, int]) -> np.ndarray:
        kwargs = {"target_sizes": [hw]}
        if self.model_type == "zoedepth":
            kwargs["source_sizes"] = [hw]  # the padding ZoeDepth's processor added is removed at this size
        try:
            res = self.processor.post_process_depth_estimation(out, **kwargs)[0]["predicted_depth"]
        except NameError:
            if self.model_type != "zoedepth":
                raise
            # transformers' PIL ZoeDepth processor calls torchvision in its post-processing (a NameError
            # without torchvision): the same steps in torch
            res = _zoe_post_process(out.predicted_depth, hw, bool(getattr(self.processor, "do_pad", True)))
        return _to_map(res, hw)

    def _depth_pro_depth(self, out, hw: tuple[int, int], focal_px: float | None) -> np.ndarray:
        """Depth Pro's metric depth (H, W) for a camera of horizontal focal length ``focal_px`` (pixels of the
        full image; None: the focal length from the predicted field of view).

        The network predicts inverse depth for a canonical camera; inverse depth scales with W / f (the
        same rescale as transformers' DepthProImageProcessor.post_process_depth_estimation, which takes
        only the predicted field of view, so it is applied here for a known focal length too)."""
        import torch

        if focal_px is None:
            focal_px = self._predicted_focal(out, hw[1])
        inv = out.predicted_depth[0].float() * (hw[1] / focal_px)
        inv = torch.nn.functional.interpolate(inv[None, None], size=hw, mode="bilinear", align_corners=False)
        depth = 1.0 / torch.clamp(inv[0, 0], min=1e-4, max=1e4)
        return depth.cpu().numpy().astype(np.float64)

    def _predicted_focal(self, out, width: int) -> float:
        fov = getattr(out, "field_of_view", None)
        if fov is None:
            raise ValueError(
                f"depth model {self.name} does not predict the field of view (use_fov_model off)"
            )
        fov_deg = float(fov.reshape(-1)[0])
        focal = 0.5 * width / math.tan(0.5 * math.radians(fov_deg))
        if not (math.isfinite(focal) and focal > 0):
            raise ValueError(
                f"depth model {self.name} predicted an unusable field of view ({fov_deg:.3g} deg)"
            )
        return focal

    def predict(self, rgb: np.ndarray, camera: Camera) -> np.ndarray:
        """Depth in metres for the image with the known ``camera``: float32 (H, W), 0 = unknown."""
        return self.scaling.to_metres(self.raw_output(rgb, camera), camera)

    def predict_with_focal(self, rgb: np.ndarray) -> tuple[np.ndarray, float]:
        """For a camera that is not known (Depth Pro with its field-of-view head): (depth in metres,
        float32 (H, W); the horizontal focal length in pixels of the full image that the model predicted,
        principal point assumed at the image centre). The scaling applies as in :meth:`predict`."""
        if not self.predicts_focal:
            raise ValueError(f"depth model {self.name} does not predict the focal length")
        h, w = rgb.shape[:2]
        check_rgb(rgb, Camera(1.0, 1.0, 0.0, 0.0, w, h))
        out = self._forward(rgb)
        focal = self._predicted_focal(out, w)
        camera = Camera(focal, focal, (w - 1) / 2, (h - 1) / 2, w, h)
        raw = self._depth_pro_depth(out, (h, w), focal)
        return self.scaling.to_metres(raw, camera), focal

    def describe(self) -> str:
        return f"depth estimated from RGB by {self.name} ({self.model_type}, {self.scaling.describe()})"


def _zoe_post_process(predicted, hw: tuple[int, int], padded: bool):
    """ZoeDepthImageProcessor.post_process_depth_estimation for one image, in torch: resize the prediction
    to the padded source size, cut the padding (int(sqrt(side / 2) * 3) per side), resize to ``hw``."""
    import torch

    d = predicted[:1, None].float()
    ph = int(math.sqrt(hw[0] / 2) * 3) if padded else 0
    pw = int(math.sqrt(hw[1] / 2) * 3) if padded else 0
    d = torch.nn.functional.interpolate(d, size=(hw[0] + 2 * ph, hw[1] + 2 * pw), mode="bicubic")
    d = d[..., ph : d.shape[-2] - ph, pw : d.shape[-1] - pw]
    return torch.nn.functional.interpolate(d, size=hw, mode="bicubic")[0, 0]


def _to_map(t, hw: tuple[int, int]) -> np.ndarray:
    a = t.detach().float().cpu().numpy().astype(np.float64)
    a = np.squeeze(a)
    if a.shape != hw:
        raise ValueError(f"the depth model's post-processed output has shape {a.shape}; expected {hw}")
    return a


class _DepthProPlainProcessor:
    """Depth Pro's preprocessing when transformers cannot build its image processor (it needs torchvision,
    which a CPU-only install may lack): the steps of ``DepthProImageProcessor`` (rescale, normalise, then
    bilinear resize to ``size``), with the values of the model's own ``preprocessor_config.json``."""

    def __init__(self, cfg: dict) -> None:
        size = cfg.get("size") or {"height": 1536, "width": 1536}
        self.size = (int(size["height"]), int(size["width"]))
        self.rescale = float(cfg.get("rescale_factor", 1 / 255)) if cfg.get("do_rescale", True) else 1.0
        self.normalize = bool(cfg.get("do_normalize", True))
        self.mean = cfg.get("image_mean", [0.5, 0.5, 0.5])
        self.std = cfg.get("image_std", [0.5, 0.5, 0.5])

    def __call__(self, images: np.ndarray, return_tensors: str = "pt") -> dict:
        import torch

        x = torch.from_numpy(np.ascontiguousarray(images)).permute(2, 0, 1).float() * self.rescale
        if self.normalize:
            mean = torch.tensor(self.mean, dtype=torch.float32)[:, None, None]
            std = torch.tensor(self.std, dtype=torch.float32)[:, None, None]
            x = (x - mean) / std
        x = torch.nn.functional.interpolate(x[None], size=self.size, mode="bilinear", align_corners=False)
        return {"pixel_values": x}

"""The "cuboids/1" result JSON shared by every part of the tool (see README, "Output schema")."""

from __future__ import annotations

import math
import os
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from cuboidcli import __version__
from cuboidcli.camera import Camera, valid_depth
from cuboidcli.cuboid import Cuboid
from cuboidcli.io.atomic import atomic_write_json
from cuboidcli.io.depth import InputWarning
from cuboidcli.io.jsonfile import misspelled, read_json, unknown_keys, warn_once

SCHEMA = "cuboids/1"
#: Frames of the cuboids: a frame's OpenCV camera coordinates, or a scan's or a sequence's own world frame.
FRAMES = ("opencv", "world")


@dataclass
class FitResult:
    """Everything a "cuboids/1" file holds. ``camera`` is None only for a ``world`` result of a bare point
    cloud or mesh, which no camera saw (a sequence's result keeps its depth camera)."""

    camera: Camera | None
    cuboids: list[Cuboid]
    settings: dict = field(default_factory=dict)
    timing_s: dict = field(default_factory=dict)
    input: dict = field(default_factory=dict)
    extras: dict = field(default_factory=dict)
    frame: str = "opencv"

    def to_json(self) -> dict:
        d = {
            "schema": SCHEMA,
            "version": __version__,
            "camera": None if self.camera is None else self.camera.to_dict(),
            "frame": self.frame,
            "cuboids": [c.to_json(i) for i, c in enumerate(self.cuboids)],
            "settings": self.settings,
            "timing_s": self.timing_s,
            "input": self.input,
        }
        d.update(self.extras)
        return d

    @classmethod
    def from_json(cls, d: dict) -> FitResult:
        """Build from a parsed "cuboids/1" document; ValueError naming the first field that is wrong."""
        check_result_json(d)
        known = {"schema", "version", "camera", "frame", "cuboids", "settings", "timing_s", "input"}
        return cls(
            camera=None if d["camera"] is None else Camera.from_dict(d["camera"]),
            cuboids=[Cuboid.from_json(c) for c in d.get("cuboids", [])],
            settings=d.get("settings", {}),
            timing_s=d.get("timing_s", {}),
            input=d.get("input", {}),
            extras={k: v for k, v in d.items() if k not in known},
            frame=d.get("frame", "opencv"),
        )


def input_record(
    depth_m: np.ndarray,
    *,
    depth: str | os.PathLike | None,
    image: str | os.PathLike | None,
    depth_source: str,
    depth_scale: float | None,
    intrinsics_source: str,
) -> dict:
    """The ``input`` entry of a frame's result: its files (None for arrays), where its depth came from (a
    depth map, a network's estimate, an array), the size and the share of valid pixels of the depth map
    (H, W) metres that was fitted, and where the intrinsics came from."""
    h, w = depth_m.shape
    return {
        "depth": None if depth is None else str(depth),
        "image": None if image is None else str(image),
        "depth_source": depth_source,
        "depth_scale": depth_scale,
        "width": w,
        "height": h,
        "valid_fraction": round(float(valid_depth(depth_m).mean()), 6),
        "intrinsics_source": intrinsics_source,
    }


def fit_info_record(info) -> dict:
    """The ``fit_info`` entry of a result: how the estimator's loop went (a
    :class:`~cuboidcli.fitting.pipeline.FitInfo`), with a frame's grid step or a room's voxel size and
    visibility."""
    shape = {"grid_step": info.grid_step} if info.kind == "frame" else {
        "voxel_m": round(info.voxel_m, 6),
        "visibility": info.visibility,
    }  # fmt: skip
    return {
        "n_points": info.n_points,
        **shape,
        "iterations": info.iterations,
        "batches": info.batches,
        "stop_reason": info.stop_reason,
        "rejected_gain": info.rejected_gain,
        "gains": info.gains,
        "align": info.align,
        "aligned": info.aligned,
        "warnings": info.warnings,
    }


def settings_record(config, info, solver_name: str, sampler_name: str, extra: dict | None = None) -> dict:
    """The ``settings`` entry: the FitConfig's fields as this input's kind reads them (``config`` resolved
    for it), the Theta used, whose random generator and which scoring backend the fit ran on, the solver's
    and sampler's names and ``extra`` (the weights used, how the input was read)."""
    return {
        **config.to_dict(info.kind),
        "theta_used": info.theta,
        "random_generator": info.random_generator,
        "backend_used": info.backend_used,
        "solver_name": solver_name,
        "sampler_name": sampler_name,
        **(extra or {}),
    }


def same_settings(saved: dict, config, extra_settings: dict | None = None) -> bool:
    """Whether a saved result's ``settings`` (as :func:`settings_record` writes them) are ``wanted``, the
    settings a fit would record now (``config``, a FitConfig resolved for the input's kind, and
    ``extra_settings``: the weights used, how the input is read): a rerun may then keep that result
    instead of fitting again. A setting the saved result lacks counts as its default: a setting is only
    added with the default that reproduces what the code did before it existed."""
    import json

    wanted = {**json.loads(json.dumps(config.to_dict())), **(extra_settings or {})}
    defaults = json.loads(json.dumps(type(config)().to_dict()))
    return all(saved.get(k, defaults.get(k)) == v for k, v in wanted.items())


def saved_settings(out_json: str | os.PathLike, outputs: list[Path]) -> dict | None:
    """The ``settings`` of a finished result: None unless every file of ``outputs`` exists and ``out_json``
    is a valid "cuboids/1" result with settings (a rerun fits it again then)."""
    if not all(Path(p).is_file() for p in outputs):
        return None
    try:
        saved = read_result(out_json)
    except (OSError, ValueError, KeyError, TypeError):
        return None
    return saved.settings if isinstance(saved.settings, dict) else None


def _is_number(v) -> bool:
    return isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)


def _numbers(v, n: int) -> bool:
    return isinstance(v, list) and len(v) == n and all(_is_number(x) for x in v)


def _check_cuboid(c, where: str) -> None:
    if not isinstance(c, dict):
        raise ValueError(f"field '{where}' must be an object with center, half_size and rotation")
    for key in ("center", "half_size"):
        if key not in c:
            raise ValueError(f"field '{where}.{key}' is missing{misspelled(key, c)}")
        if not _numbers(c[key], 3):
            raise ValueError(f"field '{where}.{key}' must be 3 finite numbers (got {c[key]!r:.60})")
    if any(a < 0 for a in c["half_size"]):
        raise ValueError(f"field '{where}.half_size' must not be negative (got {c['half_size']})")
    if "rotation" in c:
        rot = c["rotation"]
        if not (isinstance(rot, list) and len(rot) == 3 and all(_numbers(row, 3) for row in rot)):
            raise ValueError(f"field '{where}.rotation' must be a 3x3 list of finite numbers")
        r = np.asarray(rot, dtype=np.float64)
        if np.abs(r.T @ r - np.eye(3)).max() > 1e-3 or np.linalg.det(r) <= 0:
            raise ValueError(f"field '{where}.rotation' is not a rotation matrix (orthonormal, det +1)")
    elif "quat_wxyz" in c:
        q = c["quat_wxyz"]
        if not _numbers(q, 4) or math.hypot(*q) < 1e-6:
            raise ValueError(f"field '{where}.quat_wxyz' must be 4 finite numbers, not all zero")
    else:
        hint = misspelled("rotation", c) or misspelled("quat_wxyz", c)
        raise ValueError(f"field '{where}' has neither 'rotation' nor 'quat_wxyz'{hint}")
    gain = c.get("inlier_gain")
    if gain is not None and not _is_number(gain):
        raise ValueError(f"field '{where}.inlier_gain' must be a number or null (got {gain!r:.40})")


def check_result_json(d) -> None:
    """Check a parsed document against the "cuboids/1" schema (README, "Output"); ValueError naming the
    first offending field, e.g. ``field 'cuboids[2].half_size' must be 3 finite numbers``."""
    if not isinstance(d, dict):
        raise ValueError(f"not a {SCHEMA} file: it holds a JSON {type(d).__name__}, not an object")
    if d.get("schema") != SCHEMA:
        raise ValueError(f"not a {SCHEMA} file (field 'schema' is {d.get('schema')!r})")
    frame = d.get("frame", "opencv")
    if frame not in FRAMES:
        raise ValueError(f"unsupported frame {frame!r} (field 'frame'); expected one of {', '.join(FRAMES)}")
    if "camera" not in d:
        raise ValueError(
            f"field 'camera' is missing (fx, fy, cx, cy, width, height){misspelled('camera', d)}"
        )
    cam = d["camera"]
    if cam is None and frame == "world":
        cam = {}  # a bare scan's result: no camera saw it
    elif cam is None:
        raise ValueError("field 'camera' is null; a result in the 'opencv' frame needs its camera")
    elif not isinstance(cam, dict):
        raise ValueError("field 'camera' must be an object with fx, fy, cx, cy, width, height")
    for key in ("fx", "fy", "cx", "cy", "width", "height") if cam else ():
        if key not in cam:
            raise ValueError(f"field 'camera.{key}' is missing{misspelled(key, cam)}")
        if not _is_number(cam[key]):
            raise ValueError(f"field 'camera.{key}' must be a finite number (got {cam[key]!r:.40})")
    for key in ("fx", "fy", "width", "height") if cam else ():
        if cam[key] <= 0:
            raise ValueError(f"field 'camera.{key}' must be positive (got {cam[key]})")
    for key in ("width", "height") if cam else ():
        if cam[key] != int(cam[key]):
            raise ValueError(f"field 'camera.{key}' must be a whole number of pixels (got {cam[key]})")
    if "cuboids" not in d:
        raise ValueError(
            f"field 'cuboids' is missing (a list, empty when nothing was fitted){misspelled('cuboids', d)}"
        )
    if not isinstance(d["cuboids"], list):
        raise ValueError("field 'cuboids' must be a list")
    for i, c in enumerate(d["cuboids"]):
        _check_cuboid(c, f"cuboids[{i}]")
    for key in ("settings", "timing_s", "input"):
        if key in d and not isinstance(d[key], dict):
            raise ValueError(f"field '{key}' must be an object (got {type(d[key]).__name__})")


#: The top-level keys of a "cuboids/1" result: the schema's, and those the tool's fits and synthetic
#: ground truth add (a frame's gravity, a room's up, objects and frames, the size its images were drawn at).
RESULT_KEYS = (
    *("schema", "version", "camera", "frame", "cuboids", "settings", "timing_s", "input"),
    *("fit_info", "gravity", "world_from_camera", "up", "world_from_input", "objects", "frames", "room"),
    "overlay",
)
#: The keys of a cuboid of a result: the schema's, a room's frames and objects', synthetic ground truth's.
CUBOID_KEYS = (
    *("id", "kind", "center", "half_size", "rotation", "quat_wxyz", "inlier_gain", "color"),
    *("frames", "cuboids", "object", "category", "part", "visible_px", "views"),
)


def unknown_result_keys(d: dict) -> list[str]:
    """A line for each key of a checked "cuboids/1" document that the schema does not know (kept as it is,
    but a misspelled ``inlier_gian`` or ``fram`` would otherwise be dropped without a word); a cuboid's
    once for all the cuboids that have it."""
    lines = unknown_keys(d, RESULT_KEYS)
    per_cuboid: dict[str, list[int]] = {}
    for i, c in enumerate(d["cuboids"]):
        for line in unknown_keys(c, CUBOID_KEYS):
            per_cuboid.setdefault(line, []).append(i)
    for line, which in per_cuboid.items():
        where = (
            f"cuboids[{which[0]}]" if len(which) == 1 else f"{len(which)} cuboids (cuboids[{which[0]}], ...)"
        )
        lines.append(f"{where}: {line}")
    return [line.replace("; ignored", "; kept as it is") for line in lines]


def write_result(path: str | os.PathLike, result: FitResult) -> Path:
    return atomic_write_json(path, result.to_json())


def read_result(path: str | os.PathLike) -> FitResult:
    d = read_json(
        Path(path),
        ValueError,
        "{path} is not valid JSON: {e}",
        missing="result file not found: {path}",
        missing_error=FileNotFoundError,
    )
    result = FitResult.from_json(d)
    warn_once(Path(path), unknown_result_keys(d), InputWarning)
    return result

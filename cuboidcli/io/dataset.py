"""The generic dataset folder layout read by ``cuboids evaluate`` / ``cuboids train`` and written by
``cuboids synth``.

Layout (the names of frames are file stems)::

    DATASET/
      cameras.json          {"<name>": {"fx", "fy", "cx", "cy", "width", "height", "depth_scale"}, ...}
                            (or camera.json: one entry for all frames)
      depth/<name>.png      uint16 depth, depth_scale metres per unit (default 0.001); or .npy in metres
      rgb/<name>.png|.jpg   optional colour image, registered to depth
      cuboids/<name>.json   optional ground-truth cuboids ("cuboids/1"); its optional
                            "world_from_camera" (4x4, z-up world) gives the known gravity
      instances/<name>.png  optional per-pixel instance ids (uint16, 0 = none)
      splits.json           optional {"train": [names], "val": [...], "test": [...]}

A flat folder with ``<name>_depth.png`` and ``<name>_rgb.(png|jpg)`` next to ``cameras.json`` /
``camera.json`` (as in the sample frames of the NYU/TUM demos) is read as well.
"""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.io.atomic import atomic_write_json
from cuboidcli.io.depth import InputError, _imread_unchanged, read_depth, read_rgb
from cuboidcli.io.jsonfile import read_json

DEPTH_SUFFIXES = (".png", ".npy", ".npz", ".exr")
#: The message of a dataset's JSON file that does not parse (:func:`~cuboidcli.io.jsonfile.read_json`).
NOT_JSON = "{path} is not valid JSON ({e.msg} at line {e.lineno})"
RGB_SUFFIXES = (".png", ".jpg", ".jpeg")


@dataclass(frozen=True)
class Frame:
    """One frame of a dataset folder; files are read on demand."""

    name: str
    depth_path: Path
    camera: Camera
    depth_scale: float = 0.001
    rgb_path: Path | None = None
    cuboids_path: Path | None = None
    instances_path: Path | None = None

    def depth_m(self) -> np.ndarray:
        return read_depth(self.depth_path, self.depth_scale)

    def rgb(self) -> np.ndarray | None:
        return None if self.rgb_path is None else read_rgb(self.rgb_path)

    def instances(self) -> np.ndarray | None:
        """Per-pixel object ids (H, W) int32 (0 = no object) from instances/<name>.png, or None."""
        if self.instances_path is None:
            return None
        img = _imread_unchanged(self.instances_path)
        if img.ndim != 2 or not np.issubdtype(img.dtype, np.integer):
            raise InputError(
                f"{self.instances_path}: an instance image is one channel of integer object ids "
                f"(uint16 PNG), got shape {img.shape} {img.dtype}"
            )
        return img.astype(np.int32)

    def gt_cuboids(self):
        from cuboidcli.io.result import read_result

        return None if self.cuboids_path is None else read_result(self.cuboids_path).cuboids

    def gt_world_from_camera(self) -> np.ndarray | None:
        """The known camera pose in a z-up world (4, 4) from the ground-truth file's ``world_from_camera``
        (``cuboids synth`` writes the room frame there), or None. A file with a ``gravity`` entry is a
        fit whose pose was estimated, not ground truth: None as well."""
        if self.cuboids_path is None:
            return None
        from cuboidcli.io.result import read_result

        extras = read_result(self.cuboids_path).extras
        pose = extras.get("world_from_camera")
        if pose is None or "gravity" in extras:
            return None
        try:
            m = np.asarray(pose, dtype=np.float64)
        except (TypeError, ValueError):
            return None
        if m.shape not in ((4, 4), (3, 4), (3, 3)) or not np.all(np.isfinite(m)):
            return None
        rot = m[:3, :3]
        if not np.allclose(rot @ rot.T, np.eye(3), atol=1e-4):
            return None
        return m


def _load_cameras(root: Path) -> tuple[dict[str, dict], dict | None]:
    per_frame: dict[str, dict] = {}
    shared = None
    for fname in ("cameras.json", "camera.json"):
        p = root / fname
        if p.is_file():
            d = read_json(p, InputError, NOT_JSON)
            if "fx" in d:
                shared = d
            else:
                per_frame.update({k: v for k, v in d.items() if isinstance(v, dict) and "fx" in v})
    return per_frame, shared


def read_splits(root: Path) -> dict[str, list[str]]:
    """The splits of a dataset folder (its ``splits.json``: split name -> frame names); {} without one.
    InputError, naming the file, when it is not JSON or not of that shape."""
    path = Path(root) / "splits.json"
    if not path.is_file():
        return {}
    d = read_json(path, InputError, NOT_JSON)
    if not isinstance(d, dict) or not all(isinstance(v, list) for v in d.values()):
        raise InputError(f'{path} must map split names to lists of frame names ({{"train": [...], ...}})')
    return {str(k): [str(n) for n in v] for k, v in d.items()}


def _find(folder: Path, stem: str, suffixes) -> Path | None:
    for s in suffixes:
        p = folder / f"{stem}{s}"
        if p.is_file():
            return p
    return None


def list_frames(root: str | os.PathLike, split: str | None = None) -> list[Frame]:
    """Frames of a dataset folder, sorted by name (optionally those of one split)."""
    root = Path(root)
    if not root.is_dir():
        raise InputError(f"dataset folder not found: {root}")
    per_frame, shared = _load_cameras(root)
    entries: list[tuple[str, Path, Path | None]] = []
    if (root / "depth").is_dir():
        for p in sorted((root / "depth").iterdir()):
            if p.suffix.lower() in DEPTH_SUFFIXES:
                entries.append((p.stem, p, _find(root / "rgb", p.stem, RGB_SUFFIXES)))
    else:
        for p in sorted(root.iterdir()):
            stem = p.stem
            for tag in ("_depth_filled", "_depth"):
                if stem.endswith(tag) and p.suffix.lower() in DEPTH_SUFFIXES:
                    name = stem[: -len(tag)]
                    entries.append((name, p, _find(root, f"{name}_rgb", RGB_SUFFIXES)))
                    break
        # prefer the in-painted map when both raw and filled exist
        names = [e[0] for e in entries]
        entries = [e for e in entries if names.count(e[0]) == 1 or "_depth_filled" in e[1].stem]
    if not entries:
        raise InputError(f"no depth maps in {root} (expected depth/<name>.png or <name>_depth.png)")
    frames = []
    for name, dpath, rpath in entries:
        cam = per_frame.get(name, shared)
        if cam is None:
            raise InputError(f"no intrinsics for frame {name!r}: add it to {root / 'cameras.json'}")
        if "width" not in cam or "height" not in cam:
            raise InputError(f"intrinsics of frame {name!r} lack width/height")
        frames.append(
            Frame(
                name=name,
                depth_path=dpath,
                camera=Camera.from_dict(cam),
                depth_scale=float(cam.get("depth_scale", 0.001)),
                rgb_path=rpath,
                cuboids_path=_find(root / "cuboids", name, (".json",)),
                instances_path=_find(root / "instances", name, (".png",)),
            )
        )
    if split is not None:
        if not (root / "splits.json").is_file():
            raise InputError(f"--split {split}: {root} has no splits.json")
        splits = read_splits(root)
        if split not in splits:
            raise InputError(f"--split {split}: splits.json has only {', '.join(splits)}")
        wanted = set(splits[split])
        frames = [f for f in frames if f.name in wanted]
    return frames


def write_cameras(root: str | os.PathLike, cameras: dict[str, Camera], depth_scale: float = 0.001) -> Path:
    d = {name: {**cam.to_dict(), "depth_scale": depth_scale} for name, cam in sorted(cameras.items())}
    return atomic_write_json(Path(root) / "cameras.json", d)

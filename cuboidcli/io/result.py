"""The "cuboids/1" result JSON shared by every part of the tool (see README, "Output schema")."""

from __future__ import annotations

import json
import os
from dataclasses import dataclass, field
from pathlib import Path

from cuboidcli import __version__
from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.io.atomic import atomic_write_json

SCHEMA = "cuboids/1"


@dataclass
class FitResult:
    """Everything a "cuboids/1" file holds."""

    camera: Camera
    cuboids: list[Cuboid]
    settings: dict = field(default_factory=dict)
    timing_s: dict = field(default_factory=dict)
    input: dict = field(default_factory=dict)
    extras: dict = field(default_factory=dict)

    def to_json(self) -> dict:
        d = {
            "schema": SCHEMA,
            "version": __version__,
            "camera": self.camera.to_dict(),
            "frame": "opencv",
            "cuboids": [c.to_json(i) for i, c in enumerate(self.cuboids)],
            "settings": self.settings,
            "timing_s": self.timing_s,
            "input": self.input,
        }
        d.update(self.extras)
        return d

    @classmethod
    def from_json(cls, d: dict) -> FitResult:
        if d.get("schema") != SCHEMA:
            raise ValueError(f"not a {SCHEMA} file (schema is {d.get('schema')!r})")
        if d.get("frame", "opencv") != "opencv":
            raise ValueError(f"unsupported frame {d.get('frame')!r}; expected 'opencv'")
        known = {"schema", "version", "camera", "frame", "cuboids", "settings", "timing_s", "input"}
        return cls(
            camera=Camera.from_dict(d["camera"]),
            cuboids=[Cuboid.from_json(c) for c in d.get("cuboids", [])],
            settings=d.get("settings", {}),
            timing_s=d.get("timing_s", {}),
            input=d.get("input", {}),
            extras={k: v for k, v in d.items() if k not in known},
        )


def write_result(path: str | os.PathLike, result: FitResult) -> Path:
    return atomic_write_json(path, result.to_json())


def read_result(path: str | os.PathLike) -> FitResult:
    path = Path(path)
    if not path.is_file():
        raise FileNotFoundError(f"result file not found: {path}")
    try:
        d = json.loads(path.read_text(encoding="utf-8"))
    except json.JSONDecodeError as e:
        raise ValueError(f"{path} is not valid JSON: {e}") from e
    return FitResult.from_json(d)

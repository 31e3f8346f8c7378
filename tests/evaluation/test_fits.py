"""cuboidcli.evaluation.fits: an evaluation fits each frame through Fitter.fit, and --save-fits keeps the
result as the evaluation asked for it (a rerun reuses it only for the same settings)."""

from __future__ import annotations

import json
from dataclasses import dataclass, replace

import numpy as np

from cuboidcli.api import Fitter
from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.fits import fit_and_save, reusable_fit, saved_fit_path
from cuboidcli.evaluation.raycast import render_depth
from cuboidcli.fitting.config import FitConfig

CAM = Camera.preset("nyu").scaled(0.125)  # 80x60
CONFIG = FitConfig(hypotheses=48, max_cuboids=3, grid_step=2, seed=4, device="cpu")


@dataclass
class _Frame:
    name: str
    camera: Camera
    depth_scale: float = 0.001


def _depth() -> np.ndarray:
    room = Cuboid([0.0, -0.2, 2.5], [2.5, 1.5, 3.0], np.eye(3))
    box = Cuboid([0.2, 0.9, 3.0], [0.5, 0.4, 0.4], np.eye(3))
    return render_depth(CAM, [room, box]).astype(np.float32)


def test_an_evaluation_fits_through_fitter_fit_and_saves_what_it_asked_for(tmp_path, monkeypatch):
    calls = []
    real = Fitter.fit
    monkeypatch.setattr(
        Fitter, "fit", lambda self, *a, **k: calls.append(k.get("seed")) or real(self, *a, **k)
    )
    depth, frame = _depth(), _Frame("f0", CAM)
    cuboids, timing, _ = fit_and_save(frame, depth, CONFIG, None, tmp_path)
    assert calls == [CONFIG.seed]
    expected = real(Fitter(replace(CONFIG, seed=0), device="cpu"), depth, CAM, seed=CONFIG.seed)
    assert [c.to_json(i) for i, c in enumerate(cuboids)] == [
        c.to_json(i) for i, c in enumerate(expected.cuboids)
    ]
    assert timing["total"] > 0
    saved = json.loads(saved_fit_path(tmp_path, CONFIG.seed, "f0").read_text())
    assert saved["input"] == {"frame": "f0", "depth": None, "image": None, "width": 80, "height": 60,
                              "depth_scale": 0.001}  # fmt: skip
    settings = saved["settings"]
    assert settings["solver_name"] == CONFIG.solver and settings["sampler_name"] == CONFIG.sampler
    assert settings["weights"] is None and "onnx" not in settings and settings["seed"] == CONFIG.seed
    path = saved_fit_path(tmp_path, CONFIG.seed, "f0")
    assert reusable_fit(path, CONFIG, None)
    assert not reusable_fit(path, replace(CONFIG, hypotheses=64), None)
    assert not reusable_fit(path, CONFIG, tmp_path)  # other weights
    assert not reusable_fit(tmp_path / "missing.json", CONFIG, None)


@dataclass
class _PhotoFrame:
    name: str
    camera: Camera
    image: np.ndarray

    def rgb(self) -> np.ndarray:
        return self.image


def test_an_rgb_only_fit_takes_its_down_direction_from_the_images_lines(tmp_path):
    """--rgb fits the predicted depth as cuboids fit fits a photo: the image's lines (found with the frame's
    camera) give the down direction, and the saved fit records them and their time."""
    from tests.geometry.test_vanishing import render_room

    img, down = render_room(500.0, -20.0, 3.0, 30.0, seed=5)
    frame = _PhotoFrame("room", Camera(500.0, 500.0, 319.5, 239.5, 640, 480), img)
    config = replace(CONFIG, grid_step=None)
    cuboids, timing, gravity = fit_and_save(frame, None, config, None, tmp_path, rgb=True)
    assert gravity.source in ("photo lines", "lines and depth")
    assert np.degrees(np.arccos(min(1.0, float(gravity.down @ down)))) < 2.0
    assert list(timing)[:2] == ["depth", "lines"] and timing["lines"] > 0
    saved = json.loads(saved_fit_path(tmp_path, config.seed, "room").read_text())
    assert saved["gravity"]["source"] == gravity.source and saved["input"]["lines"]["focal_px"] is None

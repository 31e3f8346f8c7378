"""`cuboids fit photo.jpg --depth-model FOLDER` end to end with tiny random transformers models (offline):
every supported architecture fits a photo; Depth Pro supplies the camera when nothing else does; bad
models and relative models without a scale are one-line errors that write nothing."""

from __future__ import annotations

import json

import numpy as np
import pytest
from typer.testing import CliRunner

from cuboidcli.cli.main import app

pytest.importorskip("transformers")

#: One cuboid, quickly, whatever a random network predicts; free: its depth has no floor for gravity.
ONE = ["--hypotheses", "64", "--theta", "-1e9", "--max-cuboids", "1", "--align", "free"]


def run(*args):
    return CliRunner().invoke(app, [str(a) for a in args])


@pytest.fixture(scope="module")
def photo(tmp_path_factory):
    from PIL import Image

    rng = np.random.default_rng(0)
    rgb = rng.integers(0, 255, (60, 80, 3), dtype=np.uint8)
    path = tmp_path_factory.mktemp("photo") / "room.jpg"
    Image.fromarray(rgb).save(path)
    return path


@pytest.mark.parametrize("arch", ["da_metric", "glpn", "zoedepth", "depth_pro"])
def test_a_metric_model_folder_fits_a_photo(tmp_path, photo, hf_models, arch):
    out = tmp_path / "room.json"
    r = run("fit", photo, "--depth-model", hf_models[arch], "-o", out, *ONE)
    assert r.exit_code == 0, r.output
    d = json.loads(out.read_text())
    assert len(d["cuboids"]) == 1 and d["camera"]["width"] == 80 and d["camera"]["height"] == 60
    assert "metric" in d["input"]["depth_source"] and d["timing_s"]["depth"] > 0
    source = d["input"]["intrinsics_source"]
    if arch == "depth_pro":  # it predicts the field of view: no default camera, no warning
        assert source.startswith("depth model:") and "warning" not in r.output
        assert d["camera"]["fx"] > 0 and d["camera"]["cx"] == 39.5
    else:
        assert source.startswith("default: 63 degree") and r.output.count("warning:") == 1


def test_relative_models_need_a_scale(tmp_path, photo, hf_models):
    out = tmp_path / "rel.json"
    for arch in ("da_relative", "dpt"):
        r = run("fit", photo, "--depth-model", hf_models[arch], "-o", out, *ONE)
        assert r.exit_code == 2 and not out.exists(), r.output
        assert len(r.output.strip().splitlines()) == 1 and "gives depth only up to scale" in r.output
        assert "--relative-scale" in r.output and "--camera-height" in r.output
    # A scale lifts the refusal (what a random network's scaled output then gives is not the point here;
    # tests/depth/test_hf_depth.py checks the scaling itself).
    r = run("fit", photo, "--depth-model", hf_models["dpt"], "--relative-scale", "0.5", "-o", out, *ONE)
    assert "only up to scale" not in r.output


@pytest.mark.parametrize(
    ("model", "words"),
    [
        ("hf:nobody/no-such-depth-model", "nobody/no-such-depth-model"),
        ("bert", "not a supported depth-estimation model"),
        ("empty", "config.json"),
    ],
)
def test_a_model_that_is_not_there_or_not_a_depth_model_is_one_line(tmp_path, photo, hf_models, model, words):
    if model == "bert":
        model = hf_models["bert"]
    elif model == "empty":
        model = tmp_path / "empty"
        model.mkdir()
    out = tmp_path / "x.json"
    r = run("fit", photo, "--depth-model", model, "-o", out, *ONE)
    assert r.exit_code == 2 and not out.exists(), r.output
    assert len(r.output.strip().splitlines()) == 1 and words in r.output

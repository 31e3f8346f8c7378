"""The weights registry (cuboidcli.weights): which shipped weights a configuration picks, where a
``--weights`` value goes, the defaults and their environment overrides."""

from __future__ import annotations

import pytest
import torch

from cuboidcli import weights
from cuboidcli.weights import MODELS_DIR, checkpoint_kind, default_weights_dir, weights_for


@pytest.mark.parametrize(
    ("name", "kind"),
    [
        ("sampler_v2.pt", "sampler"),
        ("solver_v2.pt", "solver"),
        ("depth_v1.pt", "depth"),
        ("depth_v3.pt", "depth"),
        ("depth_v4.pt", "depth"),
    ],
)
def test_shipped_files_are_recognised(name, kind):
    assert checkpoint_kind(MODELS_DIR / name) == kind


def test_foreign_files_are_not_ours(tmp_path):
    text = tmp_path / "notes.pt"
    text.write_text("not a checkpoint")
    plain = tmp_path / "plain.pt"
    torch.save({"weights": torch.zeros(3)}, plain)
    assert checkpoint_kind(text) is None and checkpoint_kind(plain) is None
    # Unknown files go to every network (which then says what is wrong with them).
    assert weights_for("sampler", text) == text and weights_for("solver", plain) == plain


def test_a_weights_file_goes_only_to_its_network(tmp_path):
    solver = MODELS_DIR / "solver_v2.pt"
    assert weights_for("solver", solver) == solver
    assert weights_for("sampler", solver) is None  # the learned sampler keeps its shipped weights
    assert weights_for("sampler", tmp_path) == tmp_path  # a folder: each part picks its own file
    assert weights_for("depth", None) is None


def test_kind_is_read_once_per_file_version(tmp_path, monkeypatch):
    path = tmp_path / "w.pt"
    torch.save({"config": {"heads": 2}, "state_dict": {}}, path)
    loads = []
    real_load = torch.load
    monkeypatch.setattr(torch, "load", lambda *a, **k: loads.append(a[0]) or real_load(*a, **k))
    weights._checkpoint_kind.cache_clear()
    assert [checkpoint_kind(path) for _ in range(3)] == ["solver"] * 3
    assert len(loads) == 1
    torch.save({"config": {"maps": 4}, "state_dict": {}}, path)  # rewritten: read again
    assert checkpoint_kind(path) == "sampler" and len(loads) == 2


def test_default_bundles():
    assert default_weights_dir("numerical") is None  # top-level models/
    assert default_weights_dir("neural") == MODELS_DIR / "neural"
    assert default_weights_dir("numerical", rgb=True, builtin_depth=False) is None
    assert weights.default_depth_weights() == MODELS_DIR / "depth_v4.pt"


def test_documented_models_paths_resolve_to_the_shipped_files(tmp_path, monkeypatch):
    monkeypatch.chdir(tmp_path)  # no models/ here, as for an installed package
    assert weights.shipped_path("models/solver_v1.pt") == MODELS_DIR / "solver_v1.pt"
    assert weights.shipped_path("models/rgb/depth_v2.pt") == MODELS_DIR / "rgb" / "depth_v2.pt"
    # Other paths, and documented-looking paths that are not shipped, stay as given.
    assert weights.shipped_path("models/nothing.pt").as_posix() == "models/nothing.pt"
    assert weights.shipped_path("mine/solver.pt").as_posix() == "mine/solver.pt"
    (tmp_path / "models").mkdir()
    (tmp_path / "models" / "solver_v1.pt").write_bytes(b"local")
    assert weights.shipped_path("models/solver_v1.pt").as_posix() == "models/solver_v1.pt"


def test_version_lists_the_default_weights_with_their_hashes():
    lines = weights.describe_weights()
    assert lines[0].startswith(f"weights: {MODELS_DIR}")
    # The short hashes agree with the full ones on the model card of the neural bundle.
    card = (MODELS_DIR / "neural" / "README.md").read_text()
    neural = next(line for line in lines if "neural/solver_v2.pt" in line)
    assert neural.split("sha256 ")[1][:12] in card
    assert len(lines) == 1 + len(weights.DEFAULT_FILES) and not any("MISSING" in x for x in lines)
    # and the command prints them after its version
    from typer.testing import CliRunner

    from cuboidcli.cli.main import app

    res = CliRunner().invoke(app, ["--version"])
    assert res.exit_code == 0
    assert res.output.splitlines()[1:] == lines and res.output.startswith("cuboids ")


def test_the_wheel_ships_every_weights_file_and_model_card():
    """setup.py's build hook copies exactly these into cuboidcli/models/ of the wheel."""
    from pathlib import Path

    setup_py = Path(__file__).resolve().parents[1] / "setup.py"
    # Read the file list without running setup(): execute everything above the call.
    namespace: dict = {"__file__": str(setup_py)}
    exec(compile(setup_py.read_text().split("\nsetup(")[0], str(setup_py), "exec"), namespace)
    shipped = {p.relative_to(MODELS_DIR).as_posix() for p in namespace["shipped_files"]()}
    for _, rel in weights.DEFAULT_FILES:
        assert rel in shipped
    assert {"solver_v1.pt", "sampler_v3.pt", "rgb/depth_v2.pt", "depth_v1.pt", "README.md"} <= shipped
    assert all(name.endswith((".pt", ".md")) for name in shipped)


def test_defaults_and_their_environment_overrides(tmp_path, monkeypatch):
    for kind in weights.KINDS:
        monkeypatch.delenv(weights.ENV[kind], raising=False)
    assert weights.default_path("sampler") == MODELS_DIR / "sampler_v2.pt"
    assert weights.default_path("solver") == MODELS_DIR / "solver_v2.pt"
    assert weights.default_path("depth") == weights.default_depth_weights() == MODELS_DIR / "depth_v4.pt"
    assert all(weights.resolve(kind) == weights.default_path(kind) for kind in weights.KINDS)
    monkeypatch.setenv("CUBOIDS_SOLVER_WEIGHTS", str(tmp_path / "mine.pt"))
    assert weights.resolve("solver", None) == tmp_path / "mine.pt"


def test_resolve_a_weights_value_as_each_loader_reads_it(tmp_path):
    folder = tmp_path / "bundle"
    folder.mkdir()
    assert weights.resolve("sampler", folder) == folder / "sampler_v2.pt"
    assert weights.resolve("sampler", tmp_path / "s.pt") == tmp_path / "s.pt"
    assert weights.resolve("solver", folder) == folder / "solver_v2.pt"  # neither there: the current name
    (folder / "solver_v1.pt").write_bytes(b"")
    assert weights.resolve("solver", folder) == folder / "solver_v1.pt"  # a folder of the first release
    (folder / "solver_v2.pt").write_bytes(b"")
    assert weights.resolve("solver", folder) == folder / "solver_v2.pt"
    assert weights.resolve("depth", folder / "d.pt") == folder / "d.pt"


def test_files_loaded_by_a_configuration(tmp_path):
    assert weights.files_loaded("numerical", "sequential") == {}
    assert weights.files_loaded("neural", "learned", tmp_path) == {
        "solver": tmp_path / "solver_v2.pt",
        "sampler": tmp_path / "sampler_v2.pt",
    }
    solver = MODELS_DIR / "solver_v2.pt"  # a solver file: the sampler keeps its default
    assert weights.files_loaded("neural", "learned", solver) == {
        "solver": solver,
        "sampler": weights.default_path("sampler"),
    }

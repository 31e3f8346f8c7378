"""An output folder that cannot be written to (read-only, full): one line, exit 2, nothing partial left."""

from __future__ import annotations

import errno
import json
import os
import shutil
from pathlib import Path

import pytest
from typer.testing import CliRunner

from cuboidcli.cli.main import app
from cuboidcli.io import atomic

ROOT = Path(__file__).resolve().parents[2]
SAMPLE = ROOT / "cuboidcli" / "data" / "sample"
CAMERA = str(SAMPLE / "camera.json")
FIT = ["fit", "--depth", str(SAMPLE / "sample_depth.png"), "-K", CAMERA, "--hypotheses=64"]

runner = CliRunner()


def _error_lines(result) -> list[str]:
    return [line for line in result.output.splitlines() if line.strip()]


def _disk_full_for(monkeypatch, suffix: str, after: int = 0) -> list[Path]:
    """Make the atomic rename of files ending in ``suffix`` fail as a full disk does, after ``after`` such
    files went through; returns the list of the files that did go through."""
    real = os.replace
    done: list[Path] = []

    def replace(src, dst):
        if str(dst).endswith(suffix):
            if len(done) >= after:
                raise OSError(errno.ENOSPC, "No space left on device")
            done.append(Path(dst))
        return real(src, dst)

    monkeypatch.setattr(atomic.os, "replace", replace)
    return done


def test_a_full_disk_is_one_line_and_leaves_no_file_of_the_result(tmp_path, monkeypatch):
    """The GLB is written, then the JSON (written last) fails: the GLB this run made is removed again, no
    temporary file is left, and the user reads one line naming the file and what to do."""
    _disk_full_for(monkeypatch, ".json")
    out = tmp_path / "out"
    result = runner.invoke(app, [*FIT, "-o", str(out / "r.json"), "--glb", "--ply", "--quiet"])
    assert result.exit_code == 2, result.output
    lines = _error_lines(result)
    assert len(lines) == 1 and "cannot write" in lines[0] and "no space left" in lines[0], result.output
    assert "r.json" in lines[0]
    assert sorted(p.name for p in out.iterdir()) == []


def test_an_output_file_that_replaced_an_older_one_stays_but_new_files_go(tmp_path, monkeypatch):
    out = tmp_path / "out"
    out.mkdir()
    (out / "r.glb").write_bytes(b"an older result")
    _disk_full_for(monkeypatch, ".ply")
    result = runner.invoke(app, [*FIT, "-o", str(out / "r.json"), "--glb", "--ply", "--quiet"])
    assert result.exit_code == 2, result.output
    assert [p.name for p in out.iterdir()] == ["r.glb"]  # the new GLB over the old one, nothing else
    assert (out / "r.glb").read_bytes() != b"an older result"


def test_a_folder_stops_at_a_full_disk_and_keeps_the_results_done(tmp_path, monkeypatch):
    frames = tmp_path / "frames"
    frames.mkdir()
    for name in ("a_depth.png", "b_depth.png", "c_depth.png"):
        shutil.copy(SAMPLE / "sample_depth.png", frames / name)
    out = tmp_path / "out"
    written = _disk_full_for(monkeypatch, ".json", after=1)
    fit = ["fit", "--depth", str(frames), "-K", str(SAMPLE / "camera.json"), "--hypotheses=64"]
    result = runner.invoke(app, [*fit, "-o", str(out), "--quiet"])
    assert result.exit_code == 2, result.output
    assert "no space left" in _error_lines(result)[-1]
    assert [p.name for p in written] == ["a_depth_cuboids.json"]
    assert sorted(p.name for p in out.iterdir()) == ["a_depth_cuboids.json"]  # complete, and nothing else
    assert json.loads((out / "a_depth_cuboids.json").read_text())["schema"] == "cuboids/1"


def test_a_folder_not_writable_is_refused_before_the_fit(tmp_path, monkeypatch):
    """The command says so before it loads or fits anything (here: ``os.access`` reports the folder
    read-only, as it does for a read-only file system even for root)."""
    readonly = tmp_path / "ro"
    readonly.mkdir()
    real = os.access
    monkeypatch.setattr(os, "access", lambda p, mode: False if Path(p) == readonly else real(p, mode))
    fitted = []
    monkeypatch.setattr("cuboidcli.job.Job.run", lambda *a, **k: fitted.append(a))
    result = runner.invoke(app, [*FIT, "-o", str(readonly / "new" / "r.json")])
    assert result.exit_code == 2, result.output
    lines = _error_lines(result)
    assert len(lines) == 1 and "not writable" in lines[0] and "-o" in lines[0], result.output
    assert fitted == [] and list(readonly.iterdir()) == []


@pytest.mark.skipif(os.name != "posix" or os.geteuid() == 0, reason="root writes into read-only folders")
def test_a_read_only_folder_is_one_line(tmp_path):
    readonly = tmp_path / "ro"
    readonly.mkdir()
    readonly.chmod(0o555)
    try:
        result = runner.invoke(app, [*FIT, "-o", str(readonly / "r.json")])
    finally:
        readonly.chmod(0o755)
    assert result.exit_code == 2, result.output
    assert len(_error_lines(result)) == 1 and list(readonly.iterdir()) == []


def test_the_library_raises_an_output_error_naming_the_file(tmp_path, monkeypatch):
    import numpy as np

    import cuboidcli as cb

    depth = np.full((60, 80), 3.0, np.float32)
    depth[40:] = 1.5
    res = cb.fit(depth, cb.Camera(65, 65, 40, 30), hypotheses=32, max_cuboids=2, device="cpu")
    _disk_full_for(monkeypatch, ".png")
    with pytest.raises(atomic.OutputError, match=r"cannot write .*r_overlay\.png: no space left"):
        res.save(tmp_path / "r.json", ("glb", "overlay"))
    assert list(tmp_path.iterdir()) == []

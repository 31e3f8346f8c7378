"""Atomic writes (io/atomic.py): a write that fails leaves the old file as it was and no temporary file."""

from __future__ import annotations

import os

import pytest
import torch

from cuboidcli.io.atomic import atomic_torch_save, atomic_write, atomic_write_json, atomic_write_text


def test_a_failed_write_keeps_the_old_file_and_leaves_nothing_behind(tmp_path):
    target = tmp_path / "result.json"
    atomic_write_json(target, {"cuboids": [1, 2]})

    def half_then_fail(tmp):
        tmp.write_text('{"cuboids": [', encoding="utf-8")
        raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        atomic_write(target, half_then_fail)
    assert target.read_text(encoding="utf-8") == '{\n  "cuboids": [\n    1,\n    2\n  ]\n}\n'
    assert [p.name for p in tmp_path.iterdir()] == ["result.json"]


def test_the_writer_sees_the_targets_suffix_and_missing_folders_are_made(tmp_path):
    seen = []
    target = tmp_path / "a" / "b" / "overlay.png"
    atomic_write(target, lambda tmp: (seen.append(tmp), tmp.write_bytes(b"png")))
    assert seen[0].suffix == ".png" and seen[0].parent == target.parent and seen[0] != target
    assert target.read_bytes() == b"png" and not seen[0].exists()


def test_written_files_get_the_usual_permissions(tmp_path):
    old = os.umask(0o022)
    try:
        path = atomic_write_text(tmp_path / "x.txt", "hello")
    finally:
        os.umask(old)
    assert path.read_text(encoding="utf-8") == "hello"
    assert path.stat().st_mode & 0o777 == 0o644  # not mkstemp's 0600


def test_torch_save_round_trips(tmp_path):
    path = atomic_torch_save({"w": torch.arange(3.0)}, tmp_path / "last.pt")
    assert torch.equal(torch.load(path, weights_only=True)["w"], torch.arange(3.0))

"""Multi-process pre-training of the neural solver: ``torchrun`` with 2 CPU processes over gloo."""

from __future__ import annotations

import json
import os
import subprocess
import sys

import pytest
import torch
import torch.distributed as dist

from cuboidcli.learn.distributed import state_sha256

pytestmark = pytest.mark.skipif(
    not dist.is_available() or not dist.is_gloo_available(),
    reason="torch.distributed with the gloo backend is not available in this torch build",
)

TINY_RUN = ["--width", "16", "--layers", "1", "--heads", "2", "--ff", "32"]
TINY_RUN += ["--iters", "6", "--batch", "8", "--val-every", "3", "--backend", "gloo"]


def test_torchrun_two_processes_train_one_model(tmp_path):
    out = tmp_path / "run"
    # ``python -m torch.distributed.run`` is the torchrun console script, found without relying on PATH;
    # --standalone picks a free port, so parallel test runs do not collide.
    cmd = [sys.executable, "-m", "torch.distributed.run", "--standalone", "--nproc_per_node", "2"]
    cmd += ["-m", "cuboidcli.cli.main", "train", "solver", *TINY_RUN, "--out", str(out)]
    env = {**os.environ, "OMP_NUM_THREADS": "1"}
    env.pop("CUBOIDS_DIST_BACKEND", None)
    proc = subprocess.run(cmd, capture_output=True, text=True, timeout=120, env=env, cwd=tmp_path)
    assert proc.returncode == 0, proc.stdout + proc.stderr

    # One set of outputs, written by rank 0 alone: one line per event, one final message.
    names = sorted(p.name for p in out.iterdir())
    assert names == ["best.pt", "config.json", "last.pt", "log.jsonl", "step_0000003.pt", "step_0000006.pt"]
    assert proc.stdout.count("done at step 6") == 1
    records = [json.loads(line) for line in (out / "log.jsonl").read_text().splitlines()]
    assert [r["iteration"] for r in records if r["event"] == "val"] == [3, 6]
    assert [r["iteration"] for r in records if r["event"] == "train"] == [6]  # log_every 50: the last step
    (done,) = [r for r in records if r["event"] == "done"]
    assert done["iteration"] == 6 and done["world_size"] == 2
    config = json.loads((out / "config.json").read_text())
    assert config["distributed"] == {"world_size": 2, "backend": "gloo"}

    # Each rank hashed its own final weights: the replicas are bit-identical and rank 0 saved them.
    hashes = done["param_sha256"]
    assert len(hashes) == 2 and hashes[0] == hashes[1]
    last = torch.load(out / "last.pt", weights_only=True)
    assert last["world_size"] == 2 and state_sha256(last["state_dict"]) == hashes[0]

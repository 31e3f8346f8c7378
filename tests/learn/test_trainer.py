"""The training loop every trainer runs on (cuboidcli.learn.trainer), with a tiny job: resume, the time
limit, snapshot rotation, best-by-validation and the records it logs."""

from __future__ import annotations

import itertools
import json
from dataclasses import replace

import pytest
import torch

from cuboidcli.learn import trainer
from cuboidcli.learn.job import StepResult, TrainingJob, Validation
from cuboidcli.learn.run_config import RunConfig
from cuboidcli.learn.trainer import run_job
from cuboidcli.learn.training_state import read_state


class LineJob(TrainingJob):
    """Fits y = 2x + 1 with a 1-in 1-out linear layer and Adam, on points drawn from torch's global RNG
    (so an exact resume needs the RNG and the optimizer's moments back). Its validation returns the values
    of ``scores`` in turn (None: no validation data); ``tick`` advances a fake clock by a step's seconds."""

    name = "line"
    state_kind = "line-train-state"
    step_event = "train"
    rate_key = "points_per_s"

    def __init__(self, scores=None, lower_is_better=False, tick=None, steps_per_epoch=3):
        self.scores = scores
        self.lower_is_better = lower_is_better
        self.tick = tick
        self.steps_per_epoch = steps_per_epoch
        self.validations = 0

    def setup(self, run, state):
        self.net = torch.nn.Linear(1, 1)
        if state is not None:
            self.net.load_state_dict(state["state_dict"])
            self.validations = state["validations"]
        self.optimizer = torch.optim.Adam(self.net.parameters(), lr=0.05)

    def batches(self, run):
        return itertools.count() if run.cfg.step_based else range(self.steps_per_epoch)

    def step(self, run, batch):
        x = torch.randn(8, 1)
        loss = ((self.net(x) - (2 * x + 1)) ** 2).mean()
        self.optimizer.zero_grad()
        loss.backward()
        self.optimizer.step()
        if self.tick is not None:
            self.tick()
        return StepResult({"loss": loss.item()}, {"epoch": run.epoch + 1}, items=8)

    def validate(self, run):
        if self.scores is None:
            return None
        value = self.scores[self.validations]
        self.validations += 1
        return Validation(value, {"score": value})

    def state(self, run):
        return {"state_dict": self.net.state_dict(), "validations": self.validations}

    def networks(self):
        return {"line": self.net}

    def best_weights(self, run, validation):
        meta = {"epoch": run.epoch, "step": run.step, **validation}
        return {"line.pt": {"state_dict": self.net.state_dict(), "meta": meta}}


def records(out, event=None):
    lines = (json.loads(line) for line in (out / "log.jsonl").read_text().splitlines())
    return [r for r in lines if event is None or r["event"] == event]


def weights(path):
    return torch.load(path, weights_only=True)["state_dict"]


def test_resume_continues_steps_rng_and_optimizer(tmp_path):
    run = dict(max_epochs=4, seed=3)
    full = run_job(LineJob(), RunConfig(tmp_path / "a", **run))
    run_job(LineJob(), RunConfig(tmp_path / "b", stop_after_epochs=2, **run))
    assert read_state(tmp_path / "b" / "last.pt", LineJob.state_kind, "line")["step"] == 6
    resumed = run_job(LineJob(), RunConfig(tmp_path / "b", resume=tmp_path / "b" / "last.pt", **run))
    assert full["step"] == resumed["step"] == 12 and full["epoch"] == resumed["epoch"] == 4

    steps_a, steps_b = records(tmp_path / "a", "train"), records(tmp_path / "b", "train")
    assert [r["step"] for r in steps_b] == list(range(1, 13))  # the count goes on from the checkpoint
    assert [r["loss"] for r in steps_a] == [r["loss"] for r in steps_b]  # same draws, same Adam moments
    a, b = weights(tmp_path / "a" / "last.pt"), weights(tmp_path / "b" / "last.pt")
    assert all(torch.equal(a[k], b[k]) for k in a)
    assert full["param_sha256"] == resumed["param_sha256"]
    assert json.loads((tmp_path / "b" / "config.json").read_text())["resumed_from"].endswith("last.pt")


def test_resume_of_a_step_based_run_from_a_snapshot(tmp_path):
    cfg = dict(max_steps=6, save_every=2, keep_snapshots=3, snapshot_name="step_{step}.pt")
    run_job(LineJob(), RunConfig(tmp_path / "a", **cfg))
    run_job(LineJob(), RunConfig(tmp_path / "b", resume=tmp_path / "a" / "step_4.pt", **cfg))
    assert [r["step"] for r in records(tmp_path / "b", "train")] == [5, 6]
    a, b = weights(tmp_path / "a" / "last.pt"), weights(tmp_path / "b" / "last.pt")
    assert all(torch.equal(a[k], b[k]) for k in a)
    with pytest.raises(ValueError, match="not a line training checkpoint"):
        run_job(LineJob(), RunConfig(tmp_path / "c", resume=tmp_path / "a" / "line.pt", **cfg))


@pytest.fixture
def fake_clock(monkeypatch):
    """The loop's clock, advanced by hand: seconds[0]."""
    seconds = [0.0]
    monkeypatch.setattr(trainer, "_clock", lambda: seconds[0])
    return seconds


def _tick(seconds, by):
    def tick():
        seconds[0] += by

    return tick


def test_time_limit_stops_after_the_step_and_writes_last(tmp_path, fake_clock):
    # 10 s a step and 0.5 minutes: the third step uses the budget up; the run validates and saves there
    job = LineJob(scores=[1.0, 2.0, 3.0], tick=_tick(fake_clock, 10.0))
    final = run_job(job, RunConfig(tmp_path, max_steps=100, max_minutes=0.5, val_every=50, save_every=50))
    assert final["timed_out"] and final["step"] == 3
    state = read_state(tmp_path / "last.pt", LineJob.state_kind, "line")
    assert state["step"] == 3 and state["elapsed_s"] == pytest.approx(30.0)
    assert [r["step"] for r in records(tmp_path, "val")] == [3]
    (stop,) = records(tmp_path, "stop")
    assert stop["step"] == 3 and stop["reason"] == "max_minutes"
    assert records(tmp_path)[-1]["event"] == "end"


def test_time_limit_of_an_epoch_based_run(tmp_path, fake_clock):
    # checked after every epoch by default: 3 steps of 10 s, the limit 25 s: one whole epoch
    tick = _tick(fake_clock, 10.0)
    final = run_job(LineJob(tick=tick), RunConfig(tmp_path / "e", max_epochs=5, max_minutes=25 / 60))
    assert final["timed_out"] and (final["epoch"], final["step"]) == (1, 3)
    # within the epoch: after the second step the time is up, the epoch ends there (validated, saved)
    cfg = RunConfig(tmp_path / "s", max_epochs=5, max_minutes=15 / 60, stop_within_epoch=True)
    final = run_job(LineJob(tick=tick), cfg)
    assert final["timed_out"] and (final["epoch"], final["step"]) == (1, 2)
    assert read_state(tmp_path / "s" / "last.pt", LineJob.state_kind, "line")["step"] == 2
    # a budget over all sessions: a resumed run has used its 20 s already
    tick = _tick(fake_clock, 10.0)
    cfg = RunConfig(tmp_path / "t", max_epochs=5, max_minutes=20 / 60, minutes_span_resumes=True)
    run_job(LineJob(tick=tick), replace(cfg, stop_after_epochs=1))  # 30 s: over, but stopped by the test
    final = run_job(LineJob(tick=tick), replace(cfg, resume=tmp_path / "t" / "last.pt"))
    assert final["timed_out"] and final["epoch"] == 2 and final["elapsed_s"] == pytest.approx(60.0)


def test_snapshot_rotation_keeps_the_last_n(tmp_path):
    cfg = RunConfig(tmp_path, max_steps=7, save_every=2, keep_snapshots=2, snapshot_name="step_{step:03d}.pt")
    run_job(LineJob(), cfg)
    names = sorted(p.name for p in tmp_path.glob("step_*.pt"))
    assert names == ["step_006.pt", "step_007.pt"]  # saved at steps 2, 4, 6 and the last one, 7
    assert read_state(tmp_path / "last.pt", LineJob.state_kind, "line")["step"] == 7
    assert read_state(tmp_path / "step_006.pt", LineJob.state_kind, "line")["step"] == 6
    # epoch snapshots, and none at all with keep_snapshots 0
    run_job(LineJob(), RunConfig(tmp_path / "e", max_epochs=4, keep_snapshots=3))
    assert sorted(p.name for p in (tmp_path / "e").glob("epoch_*.pt")) == [
        f"epoch_00{i}.pt" for i in (2, 3, 4)
    ]
    run_job(LineJob(), RunConfig(tmp_path / "n", max_epochs=2))
    assert sorted(p.name for p in (tmp_path / "n").glob("*.pt")) == ["last.pt", "line.pt"]


@pytest.mark.parametrize("lower", [False, True])
def test_best_by_validation(tmp_path, lower):
    scores = [3.0, 5.0, 4.0, 7.0, 1.0]
    if lower:
        scores = [-s for s in scores]
    final = run_job(LineJob(scores=scores, lower_is_better=lower), RunConfig(tmp_path, max_epochs=5))
    vals = records(tmp_path, "val")
    assert [r["best"] for r in vals] == [True, True, False, True, False]
    assert [r["epoch"] for r in vals] == [1, 2, 3, 4, 5]
    best = torch.load(tmp_path / "line.pt", weights_only=True)
    assert best["meta"]["epoch"] == 4 and best["meta"]["score"] == scores[3]
    assert read_state(tmp_path / "last.pt", LineJob.state_kind, "line")["best"] == scores[3]
    assert final["epoch"] == 5


def test_initial_validation_is_a_candidate_only_when_the_job_says_so(tmp_path):
    cfg = RunConfig(tmp_path / "a", max_epochs=1, validate_initial=True)
    run_job(LineJob(scores=[9.0, 5.0]), cfg)
    vals = records(tmp_path / "a", "val")
    assert vals[0]["initial"] and "best" not in vals[0] and vals[1]["best"]  # a reference point only

    class Candidate(LineJob):
        initial_is_candidate = True

    run_job(Candidate(scores=[9.0, 5.0]), replace(cfg, out_dir=tmp_path / "b"))
    vals = records(tmp_path / "b", "val")
    assert vals[0]["initial"] and not vals[1]["best"]
    assert torch.load(tmp_path / "b" / "line.pt", weights_only=True)["meta"]["epoch"] == 0


def test_without_validation_the_latest_weights_are_kept(tmp_path):
    run_job(LineJob(scores=None), RunConfig(tmp_path, max_epochs=2))
    assert not records(tmp_path, "val")
    assert torch.load(tmp_path / "line.pt", weights_only=True)["meta"]["epoch"] == 2
    assert [r["best"] for r in records(tmp_path, "epoch")] == [True, True]


def test_records_and_files(tmp_path):
    final = run_job(LineJob(scores=[1.0, 2.0]), RunConfig(tmp_path, max_epochs=2, log_every=2))
    names = sorted(p.name for p in tmp_path.iterdir())
    assert names == ["config.json", "last.pt", "line.pt", "log.jsonl"]
    events = [r["event"] for r in records(tmp_path)]
    # 6 steps logged every 2 (the window restarts with each epoch: steps 2, then 4 and 6)
    assert events == ["start", "train", "val", "epoch", "train", "train", "val", "epoch", "end"]
    start = records(tmp_path, "start")[0]
    assert start["epochs"] == 2 and start["parameters"] == 2 and start["world_size"] == 1
    train = records(tmp_path, "train")
    assert [r["step"] for r in train] == [2, 4, 6] and all(r["points_per_s"] > 0 for r in train)
    epoch = records(tmp_path, "epoch")[0]
    assert set(epoch) == {"event", "epoch", "loss", "best", "seconds"}
    assert final["world_size"] == 1 and len(final["param_sha256"]) == 1 and final["epoch"] == 2


def test_states_of_the_older_trainers_read_with_todays_keys(tmp_path):
    path = tmp_path / "old.pt"
    torch.save(
        {"kind": "solver-train-state", "iteration": 7, "best_msd_m2": 0.5, "rng": torch.get_rng_state()}, path
    )
    state = read_state(path, "solver-train-state", "solver training")
    assert state["step"] == 7 and state["best"] == 0.5 and "torch_rng" in state and "iteration" not in state
    with pytest.raises(ValueError, match=r"not a depth training checkpoint \(use last.pt\)"):
        read_state(path, "depth-train-state", "depth training")


def test_a_job_without_multi_process_support_refuses_torchrun(tmp_path, monkeypatch):
    class Single(LineJob):
        distributed = False

    monkeypatch.setenv("WORLD_SIZE", "2")
    with pytest.raises(ValueError, match="cuboids train line runs in one process"):
        run_job(Single(), RunConfig(tmp_path, max_epochs=1))

"""A room's fit with more fits voting on its object boxes (``FitConfig.object_fits``,
fitting/pipeline.py): the cuboids stay the first fit's, the objects are deterministic for the seed."""

from __future__ import annotations

from dataclasses import replace

import numpy as np

from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import fit_room
from tests.fitting.test_room_fit import scanned_room


def test_more_fits_change_the_objects_but_not_the_cuboids():
    from cuboidcli.factories import make_sampler, make_solver

    config = FitConfig(seed=2, voxel_m=0.1, object_fits=1)
    solver, sampler = make_solver(config, None, None, "cpu"), make_sampler("sequential", None, "cpu")
    points = scanned_room()
    one, info_one = fit_room(points, config, solver=solver, sampler=sampler)
    steps = []
    three, info = fit_room(
        points, replace(config, object_fits=3), solver=solver, sampler=sampler,
        progress=lambda it, n, gain: steps.append(it),
    )  # fmt: skip
    assert [c.center.tolist() for c in three] == [c.center.tolist() for c in one]
    assert "object_fits" in info.timing_s and "object_fits" not in info_one.timing_s
    # the other fits' steps go on counting after the first's: the display never goes back
    assert all(b > a for a, b in zip(steps, steps[1:], strict=False)) and len(steps) > len(one)
    again, info_again = fit_room(points, replace(config, object_fits=3), solver=solver, sampler=sampler)
    assert [o.to_dict(0) for o in info_again.objects] == [o.to_dict(0) for o in info.objects]
    # the cabinet is one object in most fits: it stays, with its score scaled by the share that found it
    cabinet = [o for o in info.objects if np.linalg.norm(o.box.center[:2] - [0.45, 2.0]) < 0.3]
    assert len(cabinet) == 1 and 0 < cabinet[0].score <= 1


def test_the_voting_fits_draw_their_own_seeds_and_half_the_hypotheses(monkeypatch):
    from cuboidcli.factories import make_sampler, make_solver
    from cuboidcli.fitting import pipeline

    config = FitConfig(seed=7, voxel_m=0.1, object_fits=3, hypotheses=256)
    solver, sampler = make_solver(config, None, None, "cpu"), make_sampler("sequential", None, "cpu")
    seen = []
    real = pipeline.fit_points

    def spy(prep, cfg, *args, **kw):
        seen.append((cfg.seed, cfg.hypotheses))
        return real(prep, cfg, *args, **kw)

    monkeypatch.setattr(pipeline, "fit_points", spy)
    fit_room(scanned_room(), config, solver=solver, sampler=sampler)
    assert seen[0] == (7, 256) and len(seen) == 3
    assert [h for _, h in seen[1:]] == [256 // pipeline.VOTER_SHARE] * 2 == [128, 128]
    assert len({s for s, _ in seen}) == 3  # each fit its own draws, none the returned fit's

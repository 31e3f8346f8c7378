"""The object generators: box assemblies (cuboidcli.synth.furniture) and non-box clutter
(cuboidcli.synth.clutter), each in its own frame with the origin on the floor (or supporting surface)."""

from __future__ import annotations

import numpy as np
import pytest

from cuboidcli.synth.clutter import FLOOR_CLUTTER, SMALL_CLUTTER, person, pipe, plant
from cuboidcli.synth.furniture import FLOOR_FURNITURE, SMALL_OBJECTS, wall_cupboard

GENERATORS = {**{f"floor {k}": v[0] for k, v in FLOOR_FURNITURE.items()}}
GENERATORS.update({f"small {k}": v[0] for k, v in SMALL_OBJECTS.items()})
CLUTTER = {**{f"floor {k}": v[0] for k, v in FLOOR_CLUTTER.items()}}
CLUTTER.update({f"small {k}": v[0] for k, v in SMALL_CLUTTER.items()})


@pytest.mark.parametrize("name", sorted(GENERATORS))
def test_assemblies_stand_on_their_origin_and_support_what_they_promise(name):
    for seed in range(20):
        asm = GENERATORS[name](np.random.default_rng(seed))
        assert asm.parts
        for p in asm.parts:
            assert (p.hi > p.lo).all(), (name, p.name)
        lo, hi = asm.bounds()
        assert lo[2] == 0.0  # on the floor (or on the surface it is put on)
        # the origin is under the footprint's centre (an overhanging cabinet top shifts it by <= 1.5 cm)
        assert np.abs((lo[:2] + hi[:2]) / 2).max() <= 0.015 + 1e-12, name
        assert 0.0 < hi[2] <= 2.1
        for s in asm.surfaces:
            assert (s.hi > s.lo).all()
            # a surface is the top of a part that holds all of it
            holders = [
                p
                for p in asm.parts
                if p.hi[2] == pytest.approx(s.z)
                and (p.lo[:2] <= s.lo + 1e-12).all()
                and (s.hi <= p.hi[:2] + 1e-12).all()
            ]
            assert holders, (name, s)
            # and nothing of the piece is in the free height above it
            for p in asm.parts:
                overlaps_xy = (p.lo[:2] < s.hi).all() and (s.lo < p.hi[:2]).all()
                if overlaps_xy and p.hi[2] > s.z + 1e-9:
                    assert p.lo[2] >= s.z + s.clearance_m - 1e-9, (name, p.name, s)


def test_wall_cupboards_hang_on_the_wall():
    for seed in range(20):
        asm = wall_cupboard(np.random.default_rng(seed))
        lo, hi = asm.bounds()
        assert 1.4 <= lo[2] <= 1.7 and 0.5 <= hi[2] - lo[2] <= 0.8
        assert not asm.surfaces


@pytest.mark.parametrize("name", sorted(CLUTTER))
def test_clutter_meshes_are_closed_outward_and_stand_on_their_origin(name):
    for seed in range(10):
        asm = CLUTTER[name](np.random.default_rng(seed))
        lo, _ = asm.bounds()
        assert lo[2] == pytest.approx(0.0, abs=1e-12)
        for v, f, _ in asm.pieces:
            # merge coincident vertices (a cone's apex ring) and drop the faces that collapse; then every
            # edge is shared by exactly two faces, in opposite directions: a closed, consistently wound
            # surface, whose signed volume is positive for outward (counter-clockwise) winding
            _, merged = np.unique(np.round(v, 12), axis=0, return_inverse=True)
            f = merged.ravel()[f]
            f = f[(f[:, 0] != f[:, 1]) & (f[:, 1] != f[:, 2]) & (f[:, 2] != f[:, 0])]
            edges = np.concatenate([f[:, [0, 1]], f[:, [1, 2]], f[:, [2, 0]]])
            assert len({tuple(e) for e in edges}) == len(edges), name
            assert {tuple(e) for e in edges} == {tuple(e) for e in edges[:, ::-1]}, name
            a, b, c = (np.unique(np.round(v, 12), axis=0)[f[:, k]] for k in range(3))
            volume = np.einsum("fk,fk->f", a, np.cross(b, c)).sum() / 6.0
            assert volume > 0, name


def test_people_and_pipes_have_their_documented_size():
    for seed in range(10):
        rng = np.random.default_rng(seed)
        lo, hi = person(rng).bounds()
        assert 1.5 - 1e-9 <= hi[2] <= 1.85 + 1e-9
        lo, hi = pipe(rng, 2.7).bounds()
        assert lo[2] == 0.0 and hi[2] == pytest.approx(2.7)
        assert np.allclose((lo[:2] + hi[:2]) / 2, 0.0, atol=0.01)  # the frame origin is on its axis


def test_plant_foliage_stays_above_the_floor():
    # generator seed 190 draws foliage whose bumps would reach 2.4 cm below the pot's base
    lows = np.array([plant(np.random.default_rng(seed)).bounds()[0][2] for seed in range(400)])
    assert lows.min() >= 0.0

"""The room-scale estimator (fitting/room.py, fitting/pipeline.py fit_room) on a room given as points, and
the frame's fit it must leave unchanged."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.evaluation.iou import box_iou
from cuboidcli.fitting.config import FitConfig
from cuboidcli.fitting.pipeline import fit_room
from cuboidcli.fitting.room import fitting_voxels
from cuboidcli.geometry.free_side import free_side_normals
from tests.conftest import simple_room

CABINET = Cuboid(np.array([0.45, 2.0, 0.5]), np.array([0.3, 0.6, 0.5]), np.eye(3))


def _plane(rng, origin, e1, e2, n):
    uv = rng.uniform(0, 1, (n, 2))
    return np.asarray(origin) + uv[:, :1] * np.asarray(e1) + uv[:, 1:] * np.asarray(e2)


def scanned_room(seed: int = 0) -> np.ndarray:
    """Points (N, 3), z up, of a 4 x 3 x 2.5 m room's floor and four walls and of a cabinet (0.6 x 1.2 x
    1.0 m) against the wall x = 0: its top and the three faces that are not against the wall."""
    rng = np.random.default_rng(seed)
    parts = [
        _plane(rng, [0, 0, 0], [4, 0, 0], [0, 3, 0], 9000),
        _plane(rng, [0, 0, 0], [4, 0, 0], [0, 0, 2.5], 5000),
        _plane(rng, [0, 3, 0], [4, 0, 0], [0, 0, 2.5], 5000),
        _plane(rng, [0, 0, 0], [0, 3, 0], [0, 0, 2.5], 4000),
        _plane(rng, [4, 0, 0], [0, 3, 0], [0, 0, 2.5], 4000),
        _plane(rng, [0.15, 1.4, 1.0], [0.6, 0, 0], [0, 1.2, 0], 1500),
        _plane(rng, [0.75, 1.4, 0], [0, 1.2, 0], [0, 0, 1.0], 2000),
        _plane(rng, [0.15, 1.4, 0], [0.6, 0, 0], [0, 0, 1.0], 1000),
        _plane(rng, [0.15, 2.6, 0], [0.6, 0, 0], [0, 0, 1.0], 1000),
    ]
    pts = np.concatenate(parts)
    inside = np.all(np.abs(pts - CABINET.center) < CABINET.half_size - 0.01, axis=1)
    pts = pts[~inside]
    return pts + rng.normal(0, 0.004, pts.shape)


@pytest.fixture(scope="module")
def parts():
    from cuboidcli.factories import make_sampler, make_solver

    config = FitConfig(seed=2, object_fits=1)  # one fit: these tests are about its cuboids and rules
    return config, make_solver(config, None, None, "cpu"), make_sampler("sequential", None, "cpu")


def _fit(parts, points, viewpoints=None, **room):
    config, solver, sampler = parts
    config = replace(config, voxel_m=0.1, **room)
    return fit_room(points, config, solver=solver, sampler=sampler, viewpoints=viewpoints)


def test_a_scanned_room_gives_its_floor_walls_and_boxes_on_the_cabinet(parts):
    cuboids, info = _fit(parts, scanned_room())
    assert info.visibility == "views" and info.room_up.source == "estimated"
    assert abs(abs(info.room_up.up[2]) - 1.0) < 1e-3 and info.room_up.up[2] > 0
    kinds = [c.kind for c in cuboids]
    assert kinds.count("floor") == 1 and kinds.count("wall") >= 3
    floor = cuboids[kinds.index("floor")]
    assert abs(floor.center[2] + floor.half_size.min()) < 0.05  # its top face at z = 0
    # A bare cloud's cabinet faces that look away from the room's middle are taken as seen from inside
    # the cabinet, so the cabinet comes as boxes on its faces rather than one box.
    near = [
        c
        for c in cuboids
        if c.kind == "object" and np.all(np.abs(c.center - CABINET.center) < CABINET.half_size + 0.1)
    ]
    assert near and max(box_iou(c, CABINET) for c in near) > 0.05
    # the cabinet as one object: a box around all its faces, standing on the floor (its face boxes: an IoU
    # of 0.15-0.20 over seeds 0-5 with numpy's generator)
    best = max(info.objects, key=lambda o: box_iou(o.box, CABINET))
    assert box_iou(best.box, CABINET) > 0.6 > 0.25 > max(box_iou(c, CABINET) for c in near)
    assert abs(best.box.corners()[:, 2].min()) < 0.05 and set(best.cuboids) <= set(range(len(cuboids)))
    assert len(cuboids) <= 12
    # every input point has a label: the cabinet's points mostly belong to the cabinet's box
    assert info.point_labels.shape == (len(info.point_labels),) and info.point_labels.max() < len(cuboids)


def test_without_free_space_a_box_swallows_the_room(parts):
    """Counting points inside a box against it is not enough for a room: the box around the room's
    interior has every wall on its surface. Free space seen from the surfaces (views) is what stops it."""
    cuboids, _ = _fit(parts, scanned_room(), visibility="inside")
    first = cuboids[0]
    assert np.all(2 * first.half_size > 1.5)  # a room-sized solid
    views, _ = _fit(parts, scanned_room())
    assert views[0].half_size.min() < 0.05  # a slab


def test_the_same_seed_gives_the_same_room(parts):
    a, _ = _fit(parts, scanned_room())
    b, _ = _fit(parts, scanned_room())
    assert len(a) == len(b)
    for x, y in zip(a, b, strict=True):
        assert np.array_equal(x.center, y.center) and np.array_equal(x.half_size, y.half_size)


def test_a_given_up_is_used(parts):
    pts = scanned_room()[:, [0, 2, 1]] * np.array([1.0, -1.0, 1.0])  # y down
    _, info = _fit(parts, pts, up=(0.0, -1.0, 0.0))
    assert info.room_up.source == "given" and np.allclose(info.room_up.up, [0, -1, 0])


def test_fitting_voxels_grow_until_the_points_fit():
    pts = scanned_room()
    voxel, means, inverse, first = fitting_voxels(pts, 0.02, 3000)
    assert len(means) <= 3000 and voxel > 0.02
    assert inverse.shape == (len(pts),) and first.shape == (len(means),)
    # each voxel's first point lies in that voxel
    assert np.all(inverse[first] == np.arange(len(means)))


def test_a_surface_is_seen_from_the_side_where_rays_cross_empty_space():
    """A crate on the floor has a face turned away from the room's middle, yet rays from that face cross
    the room while rays into the crate meet its other faces: its normal points out of the crate. Walls face
    the room (behind them nothing is known)."""
    rng = np.random.default_rng(0)
    room = scanned_room()
    crate = Cuboid(np.array([3.0, 1.5, 0.3]), np.array([0.3, 0.3, 0.3]), np.eye(3))
    u = rng.uniform(-1, 1, (4000, 3))
    k = rng.integers(0, 3, 4000)
    u[np.arange(4000), k] = np.sign(u[np.arange(4000), k])
    box = crate.center + u * crate.half_size
    box = box[box[:, 2] > 0.01]  # not its bottom
    pts = np.concatenate([room, box])
    normals = np.zeros_like(pts)
    inside = np.array([2.0, 1.5, 1.25])
    # the crate's face y = 1.2 looks at the wall y = 0, away from the room's middle
    face = (np.abs(pts[:, 1] - 1.2) < 0.005) & (np.abs(pts[:, 0] - 3.0) < 0.25) & (pts[:, 2] > 0.05)
    wall = (pts[:, 0] < 0.005) & (pts[:, 2] > 1.2)
    normals[face] = [0.0, 1.0, 0.0]  # signs as PCA may give them: into the crate
    normals[wall] = [-1.0, 0.0, 0.0]
    out = free_side_normals(pts, normals, inside, 0.1)
    assert np.mean(out[face, 1] < 0) > 0.8  # turned out of the crate, towards y = 0
    assert np.all(out[wall, 0] > 0)  # the wall faces the room


def test_the_learned_sampler_is_refused_for_a_room(parts):
    config, solver, _ = parts

    class Learned:
        name = "learned"

    with pytest.raises(ValueError, match="sequential"):
        fit_room(scanned_room(), config, solver=solver, sampler=Learned())


_SIDE = [[-1, 0, 0], [0, 0, -1], [0, -1, 0]]  # the back wall's and the floor's axes
_BACK = [[0, 1, 0], [0, 0, -1], [-1, 0, 0]]  # the left wall's and the cabinet's
_YAWED = [[0.9223009, 0.3864724, 0], [0, 0, -1], [-0.3864725, 0.9223009, 0]]  # the rotated box's
#: What the frame of test_a_single_depth_map_fits_as_before fitted before the room estimator existed: each
#: cuboid's kind, centre (m), half size (m) and rotation, and the inlier-count gains.
PINNED = [
    ("wall", [-0.0028434, -0.0743227, 4.5022020], [1.8971564, 0.0022018, 1.4999996], _SIDE),
    ("wall", [-1.9294516, -0.0440326, 3.7384706], [0.7105737, 0.0294514, 1.4999998], _BACK),
    ("object", [1.1854783, 0.8969882, 3.8676004], [0.2676006, 0.3854785, 0.4969881], _BACK),
    ("object", [-0.4920529, 1.0598506, 2.9803209], [0.4851367, 0.3849922, 0.2598506], _YAWED),
    ("floor", [-0.0102441, 1.4029644, 3.9365206], [1.8499998, 0.6045088, 0.0029642], _SIDE),
]
PINNED_GAINS = [2083.682803027642, 714.2192453368731, 313.9833120977162, 331.0336718981616, 173.375717202713]


def test_a_single_depth_map_fits_as_before():
    """Pinned before the room estimator existed: the same kinds, in the same order, and the same cuboids and
    gains up to the CPU's rounding, so that a change of what is fitted fails it and a sum taken in another
    order does not. The bounds (3 cm, 0.001 of a rotation's entry, 0.1 % of a gain) admit what another CPU's
    vector kernels gave: an AVX-512 machine moved one wall by 1.4 mm and the turned box by 2.4 cm, and the
    gains by at most 0.035 %, against the values pinned on another. Fitted on tensors, whose random numbers
    (torch's generator) are those the values were pinned with; a frame on numpy arrays draws numpy's."""
    from cuboidcli.factories import make_sampler, make_solver
    from cuboidcli.fitting.pipeline import estimate
    from cuboidcli.fitting.prepare import frame_input
    from cuboidcli.synth.render import render_boxes

    cam = Camera.preset("nyu")
    depth, _ = render_boxes(simple_room(), cam)
    config = FitConfig(seed=5, hypotheses=512, max_cuboids=5)
    inp = frame_input(depth, cam, config.for_kind("frame")).as_tensors()
    cub, info = estimate(inp, config, solver=make_solver(config), sampler=make_sampler(config.sampler))
    assert [c.kind for c in cub] == [kind for kind, *_ in PINNED]
    for c, (_, center, half_size, rotation) in zip(cub, PINNED, strict=True):
        np.testing.assert_allclose(c.center, center, atol=0.03)
        np.testing.assert_allclose(c.half_size, half_size, atol=0.03)
        np.testing.assert_allclose(c.rotation, rotation, atol=1e-3)
    np.testing.assert_allclose(info.gains, PINNED_GAINS, rtol=1e-3)


def test_the_fused_surface_refinement_equals_the_torch_one():
    import torch

    from cuboidcli.fitting.room_backend import refine_surface, refine_surface_fused
    from cuboidcli.geometry.rotations import axis_angle_to_matrix

    rng = np.random.default_rng(0)
    a = np.array([0.5, 0.3, 0.2])
    R = axis_angle_to_matrix(torch.tensor([0.1, 0.2, 0.3], dtype=torch.float64)).numpy()
    u = rng.uniform(-1, 1, (500, 3))
    k = rng.integers(0, 3, 500)
    u[np.arange(500), k] = np.sign(u[np.arange(500), k])
    pts = torch.from_numpy((u * a) @ R.T + np.array([1.0, 2.0, 0.5]))
    start = (
        torch.tensor([1.03, 1.98, 0.52], dtype=torch.float64),
        torch.tensor([0.45, 0.33, 0.18], dtype=torch.float64),
        axis_angle_to_matrix(torch.tensor([0.12, 0.18, 0.31], dtype=torch.float64)),
    )
    ref = refine_surface(pts, *start, 1e-3, 2.0)
    fused = refine_surface_fused(pts, *start, 1e-3, 2.0)
    for x, y in zip(ref, fused, strict=True):
        assert torch.allclose(x, y, atol=1e-6)
    # and it moves towards the true box
    assert np.abs(fused[0].numpy() - [1.0, 2.0, 0.5]).max() < np.abs(start[0].numpy() - [1.0, 2.0, 0.5]).max()


def test_seen_from_inside_a_room_a_wall_is_a_wall_and_a_screen_is_not():
    """An upright slab counts only what lies right behind it (a corridor seen through a door, beyond the
    plane of the wall beside the door but not behind that wall, is no reason to doubt it), unless a quarter
    of the room lies beyond its plane: then it stands in the room (a screen whose back hides the wall
    behind it)."""
    from cuboidcli.fitting.shell import cuboid_kind

    room = scanned_room()
    down, inside = np.array([0.0, 0.0, -1.0]), np.array([2.0, 1.5, 1.25])
    corridor = np.random.default_rng(1).uniform([-3.0, -3.0, 0.0], [-0.5, -0.5, 2.5], (4000, 3))
    pts = np.concatenate([room, corridor])
    wall = Cuboid(np.array([2.0, -0.005, 1.25]), np.array([2.0, 0.005, 1.25]), np.eye(3))
    assert cuboid_kind(pts, wall, down, inside) == "wall"
    screen = Cuboid(np.array([2.5, 1.5, 1.0]), np.array([0.01, 0.3, 0.2]), np.eye(3))
    hidden = (pts[:, 0] > 2.5) & (np.abs(pts[:, 1] - 1.5) < 0.45) & (np.abs(pts[:, 2] - 1.0) < 0.35)
    assert cuboid_kind(pts[~hidden], screen, down, inside) == "object"


def test_a_low_upright_slab_is_furniture_not_a_wall():
    """The back of a sofa has the room on one side like a wall, but its top is far below the room's."""
    from cuboidcli.fitting.room import WALL_TOP_GAP_M, low_walls_are_furniture

    points = np.random.default_rng(0).uniform([0, 0, 0], [4, 3, 2.5], (2000, 3))
    wall = Cuboid([4.0, 1.5, 1.25], [0.005, 1.5, 1.25], np.eye(3), kind="wall")
    back = Cuboid([3.5, 1.5, 0.45], [0.005, 1.2, 0.45], np.eye(3), kind="wall")
    high = Cuboid([3.0, 1.5, 1.4], [0.005, 0.5, 0.5], np.eye(3), kind="wall")  # top 0.6 m below 2.5 m
    just = Cuboid([2.0, 1.5, 1.6], [0.005, 0.5, 0.45], np.eye(3), kind="wall")  # top 0.45 m below
    table = Cuboid([1.0, 1.0, 0.7], [0.4, 0.3, 0.01], np.eye(3))
    cuboids = [wall, back, high, just, table]
    low_walls_are_furniture(cuboids, points, np.array([0.0, 0.0, 1.0]))
    assert [c.kind for c in cuboids] == ["wall", "object", "object", "wall", "object"]
    assert 0.45 < WALL_TOP_GAP_M < 0.6
    turned = Cuboid([0.45, 1.5, 3.5], [0.45, 1.2, 0.005], np.eye(3), kind="wall")  # up is +x here
    low_walls_are_furniture([turned], points[:, ::-1], np.array([1.0, 0.0, 0.0]))
    assert turned.kind == "object"


def test_a_wall_whose_top_the_scan_missed_stays_a_wall():
    """Real scans often stop at 1.5-2 m: a slab as tall and long as a stretch of wall is still a wall when
    its top is far below the room's; one a little shorter either way is furniture."""
    from cuboidcli.fitting.room import CUT_WALL_LONG_M, CUT_WALL_TALL_M, low_walls_are_furniture

    points = np.random.default_rng(0).uniform([0, 0, 0], [4, 3, 2.5], (2000, 3))
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    yaw = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def slab(length, height, rotation=np.eye(3)):
        return Cuboid([0.2, 1.5, height / 2], [0.005, length / 2, height / 2], rotation, kind="wall")

    cut = slab(3.0, 1.4)
    turned = slab(1.6, 1.25, yaw)
    narrow = slab(1.4, 1.6)
    low = slab(3.0, 1.1)
    low_walls_are_furniture([cut, turned, narrow, low], points, np.array([0.0, 0.0, 1.0]))
    assert [c.kind for c in (cut, turned, narrow, low)] == ["wall", "wall", "object", "object"]
    assert (CUT_WALL_TALL_M, CUT_WALL_LONG_M) == (1.2, 1.5)
    # with up along +x: 1.6 m tall along x, 2 m long along z
    on_side = Cuboid([0.8, 0.2, 1.5], [0.8, 0.005, 1.0], np.eye(3), kind="wall")
    low_walls_are_furniture([on_side], points[:, ::-1], np.array([1.0, 0.0, 0.0]))
    assert on_side.kind == "wall"


def test_a_box_reaching_beyond_the_scanned_room_is_a_wall():
    """A scan holds its whole room: an object cuboid with 30 % or more of its volume beyond the room's outline
    seen from above is a wall fitted with the thickness of what is behind it; one less beyond stays an
    object, and so does a box inside; other kinds stay as they are."""
    from cuboidcli.fitting.room import BEYOND_SHARE, beyond_the_room_is_wall
    from cuboidcli.geometry.plan import SAMPLES

    points = scanned_room()
    up = np.array([0.0, 0.0, 1.0])

    def box(x0, x1, kind="object"):  # a box from x0 to x1 across the room's wall at x = 4
        return Cuboid([(x0 + x1) / 2, 1.5, 1.0], [(x1 - x0) / 2, 0.5, 1.0], np.eye(3), kind=kind)

    # 11 samples 10 cm apart along x: 4 of them beyond x = 4 (the last inside at 3.95 m), or 3
    behind, edge, cabinet = box(3.35, 4.35), box(3.25, 4.25), box(0.15, 0.75)
    floor = box(3.35, 4.35, kind="floor")
    beyond_the_room_is_wall([behind, edge, cabinet, floor], points, up)
    assert [c.kind for c in (behind, edge, cabinet, floor)] == ["wall", "object", "object", "floor"]
    assert SAMPLES == 11 and 3 / 11 < BEYOND_SHARE <= 4 / 11
    on_side = Cuboid([1.0, 1.5, 4.0], [1.0, 0.5, 0.5], np.eye(3))  # the same room with up along +x
    beyond_the_room_is_wall([on_side], points[:, ::-1], np.array([1.0, 0.0, 0.0]))
    assert on_side.kind == "wall"
    beyond_the_room_is_wall([edge], points[:2], up)  # too few points for an outline: nothing changes
    assert edge.kind == "object"
    beyond_the_room_is_wall([edge], points, up, share=3 / 11)  # a looser bound takes it
    assert edge.kind == "wall"


def test_a_sequence_is_held_to_its_outline_more_loosely_than_a_scan(parts, monkeypatch):
    """A sequence's points end where its views ended (the front of a refrigerator in a corner): its cuboids
    become walls only from a larger share beyond that outline."""
    import cuboidcli.fitting.room as room_module

    assert room_module.BEYOND_SHARE < room_module.BEYOND_SHARE_SEEN == 0.45
    shares = []
    monkeypatch.setattr(room_module, "beyond_the_room_is_wall", lambda *a: shares.append(a[3]))
    points = scanned_room()
    _fit(parts, points, max_cuboids=2)
    _fit(parts, points, np.tile([2.0, 1.5, 1.2], (len(points), 1)), max_cuboids=2)
    assert shares == [room_module.BEYOND_SHARE, room_module.BEYOND_SHARE_SEEN]


def test_the_room_s_slabs_open_behind_are_judged_from_inside_it(parts, monkeypatch):
    """After the outline rule the fit asks each object slab what lies behind it, seen from the room's inside
    point: the cameras' mean position for a sequence."""
    import cuboidcli.fitting.room as room_module

    seen = []
    monkeypatch.setattr(room_module, "open_behind_is_wall", lambda *a: seen.append(a))
    points = scanned_room()
    _fit(parts, points, np.tile([2.0, 1.5, 1.2], (len(points), 1)), max_cuboids=2)
    cuboids, fitting_points, up, viewpoint = seen[0]
    assert len(cuboids) == 2 and fitting_points.shape[1] == 3 and np.allclose(up, [0.0, 0.0, 1.0], atol=0.02)
    np.testing.assert_allclose(viewpoint, [2.0, 1.5, 1.2])


def test_the_real_living_room_fragment_stands_upright_without_an_up_hint():
    """The real living-room fragment is stored in a camera's frame (y down): fitted with no --up, its large
    wall is a wall (not a ceiling, as with z up), and the fit says in one warning that its up is unsure."""
    from tests.conftest import SHARED_DATA

    path = SHARED_DATA / "scans" / "livingroom_fragment.pcd"
    if not path.is_file():
        pytest.skip("../shared/data/scans is not here")
    import cuboidcli

    doc = cuboidcli.Fitter(seed=0).fit(path).record.to_json()
    assert doc["up"]["source"] == "camera"
    assert np.dot(doc["up"]["up"], [0.0, -1.0, 0.0]) > 0.99
    largest = max(doc["cuboids"], key=lambda c: c["inlier_gain"])
    assert largest["kind"] == "wall"
    assert not any(c["kind"] == "floor" for c in doc["cuboids"])
    assert "up direction unsure" in doc["up"]["warning"]


def test_a_low_level_slab_is_floor():
    """A level slab of half a square metre or more whose top is at most 25 cm above the floor under it is a
    stretch of floor (a bent floor, a step); a seat at 35 cm, a small slab, a thick box, an upright slab and
    a slab with no floor cuboid in the room stay objects."""
    from cuboidcli.fitting.room import LOW_SLAB_AREA_M2, LOW_SLAB_TOP_M, low_slabs_are_floor

    up = np.array([0.0, 0.0, 1.0])
    floor = Cuboid([2.0, 1.5, -0.02], [2.0, 1.5, 0.02], np.eye(3), kind="floor")  # its top at z = 0
    c, s = np.cos(np.radians(30)), np.sin(np.radians(30))
    yaw = np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])

    def slab(top, width, depth, thick=0.04, rotation=np.eye(3), x=1.0):
        return Cuboid([x, 1.0, top - thick / 2], [width / 2, depth / 2, thick / 2], rotation)

    step = slab(0.24, 1.0, 0.5, rotation=yaw)  # 0.5 m2, top 24 cm up
    seat = slab(0.27, 1.0, 0.8)
    small = slab(0.1, 0.7, 0.7)  # 0.49 m2
    thick = slab(0.2, 1.0, 1.0, thick=0.15)
    upright = Cuboid([1.0, 1.0, 0.12], [0.5, 0.02, 0.12], np.eye(3))
    far = slab(0.1, 1.0, 1.0, x=4.5)  # its centre 0.5 m beyond the floor's edge: its floor is still that one
    cuboids = [floor, step, seat, small, thick, upright, far]
    low_slabs_are_floor(cuboids, up)
    assert [c.kind for c in cuboids] == ["floor", "floor", "object", "object", "object", "object", "floor"]
    assert (LOW_SLAB_TOP_M, LOW_SLAB_AREA_M2) == (0.25, 0.5)
    # heights count from the floor, not from the frame's origin: the same room 1 m higher
    high_floor = Cuboid([2.0, 1.5, 0.98], [2.0, 1.5, 0.02], np.eye(3), kind="floor")
    high_step, high_seat = slab(1.24, 1.0, 0.5), slab(1.27, 1.0, 0.8)
    low_slabs_are_floor([high_floor, high_step, high_seat], up)
    assert (high_step.kind, high_seat.kind) == ("floor", "object")
    lone = slab(0.1, 1.0, 1.0)
    low_slabs_are_floor([lone], up)  # no floor to stand on
    assert lone.kind == "object"
    # a table top taken for a floor (a bare cloud's) does not make the table beside it floor: the slab's
    # top is measured from the lowest floor
    taken = Cuboid([2.7, 1.0, 0.7], [0.5, 0.5, 0.02], np.eye(3), kind="floor")
    table = slab(0.72, 1.0, 1.0, x=2.0)
    low_slabs_are_floor([taken, floor, table], up)
    assert table.kind == "object"
    # up along +x
    on_side = Cuboid([0.1, 1.0, 1.0], [0.02, 0.5, 0.5], np.eye(3))
    side_floor = Cuboid([-0.02, 1.5, 2.0], [0.02, 1.5, 2.0], np.eye(3), kind="floor")
    low_slabs_are_floor([side_floor, on_side], np.array([1.0, 0.0, 0.0]))
    assert on_side.kind == "floor"


def test_a_sequence_s_up_is_its_cameras_not_a_camera_frame_guess(parts, monkeypatch):
    """The fit tells the up estimate whether the hint is the cameras' mean up: with viewpoints (a fused
    sequence) no camera frame is guessed; a bare cloud may be one."""
    import cuboidcli.fitting.room as room_module

    asked = []
    real = room_module.room_up
    monkeypatch.setattr(room_module, "room_up", lambda *a, **k: asked.append(k["cameras"]) or real(*a, **k))
    points = scanned_room()
    _fit(parts, points, max_cuboids=1)
    _fit(parts, points, np.tile([2.0, 1.5, 1.2], (len(points), 1)), max_cuboids=1)
    assert asked == [False, True]

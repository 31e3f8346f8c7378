"""One synthetic RGB-D frame with ground-truth cuboids: room, furniture, clutter, camera, rendering."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import asdict, dataclass, field

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.synth.layout import add_clutter, add_furniture, add_lights, add_small_objects, camera_spot
from cuboidcli.synth.mesh import Soup, build_soup
from cuboidcli.synth.placement import Occupancy
from cuboidcli.synth.render import RayCaster
from cuboidcli.synth.room import build_room
from cuboidcli.synth.sensor import SensorOptions, simulate_depth
from cuboidcli.synth.shading import shade
from cuboidcli.synth.view import choose_view
from cuboidcli.synth.world import World


@dataclass(frozen=True)
class SceneOptions:
    """How scenes are generated. Ranges are (low, high), inclusive for counts."""

    sensor: SensorOptions = field(default_factory=SensorOptions)
    """Depth sensor model applied to the exact depth (see :class:`SensorOptions`)."""
    furniture: tuple[int, int] = (3, 9)
    """Pieces of furniture attempted per room (some may not fit)."""
    small_objects: tuple[int, int] = (1, 6)
    """Small objects (boxes, books, vases...) attempted on tables, desks and shelves."""
    clutter: tuple[int, int] = (1, 4)
    """Non-box objects attempted on the floor (bins, lamps, plants, people...)."""
    camera_height_m: tuple[float, float] = (1.2, 1.8)
    """Camera height above the floor, metres."""
    pitch_deg: tuple[float, float] = (-30.0, 10.0)
    """Camera pitch, degrees (negative looks down)."""
    roll_sigma_deg: float = 2.0
    """Standard deviation of the camera roll, degrees (clipped at 2.5 sigma)."""
    shadows: bool = True
    """Cast shadows from the brightest light (costs one more ray per pixel)."""
    rgb_noise: float = 0.01
    """Colour sensor noise, standard deviation in [0, 1] units of the encoded image."""
    threads: int = 0
    """Ray-casting threads (0 = all cores); results do not depend on it."""

    def to_dict(self) -> dict:
        """The options that shape the output (``threads`` does not, and is left out)."""
        d = asdict(self)
        d.pop("threads")
        return d


@dataclass
class Scene:
    """A rendered frame. Images are (H, W) / (H, W, 3) for the camera's width W and height H.

    ``depth_m`` float32 sensor depth in metres (0 = hole); ``depth_clean_m`` float32 exact z-depth (0 = no
    surface); ``rgb`` uint8; ``instances`` int32 object ids (0 = nothing). ``cuboids`` are the ground-truth
    boxes in the OpenCV camera frame (metres), one per visible box part, with extras ``object`` (its
    instance id), ``category``, ``part`` and ``visible_px`` (pixels where that part is seen). ``objects``
    lists every visible object: id, category, kind ("boxes" or "mesh") and visible_px.
    ``world_from_camera`` (4, 4) is the camera pose in the z-up room frame.
    """

    camera: Camera
    depth_m: np.ndarray
    depth_clean_m: np.ndarray
    rgb: np.ndarray
    instances: np.ndarray
    cuboids: list[Cuboid]
    objects: list[dict]
    world_from_camera: np.ndarray
    seed: list[int]
    room: dict = field(default_factory=dict)


def _count(rng: np.random.Generator, bounds: tuple[int, int]) -> int:
    return int(rng.integers(bounds[0], bounds[1] + 1))


def build_world(rng: np.random.Generator, options: SceneOptions) -> tuple[World, np.ndarray]:
    """A furnished room and a camera position (3,) in it (world frame, z up, metres)."""
    world, occ = World(), Occupancy()
    room = build_room(world, occ, rng)
    position = camera_spot(room, occ, rng, options.camera_height_m)
    placed = add_furniture(world, occ, room, _count(rng, options.furniture), rng)
    add_small_objects(world, occ, room, placed, _count(rng, options.small_objects), rng)
    add_clutter(world, occ, room, _count(rng, options.clutter), rng)
    add_lights(world, room, rng)
    world.room = {
        "size_m": [float(v) for v in room.size],
        "walls": [bool(s.present) for s in room.sides],
        "doorway": next(([k, *map(float, s.doorway)] for k, s in enumerate(room.sides) if s.doorway), None),
    }
    return world, position


def random_streams(seed: int | Sequence[int]) -> tuple[np.random.Generator, ...]:
    """The four independent generators of a frame: layout, view, depth sensor, colour sensor.

    Separate streams keep, e.g., the room unchanged when the depth noise is switched off.
    """
    return tuple(np.random.default_rng(s) for s in np.random.SeedSequence(seed_entropy(seed)).spawn(4))


def seed_entropy(seed: int | Sequence[int]) -> list[int]:
    """A seed (an int or a sequence of ints) as the list of ints its random streams are spawned from."""
    return [int(seed)] if np.isscalar(seed) else [int(s) for s in seed]


def world_caster(world: World, options: SceneOptions) -> tuple[Soup, RayCaster]:
    """The triangle soup of a world and the ray caster over it (built once, cast from every view)."""
    soup = build_soup(world)
    return soup, RayCaster(soup.vertices, soup.faces, threads=options.threads)


def generate_scene(
    seed: int | Sequence[int], camera: Camera | None = None, options: SceneOptions | None = None
) -> Scene:
    """Generate and render one frame.

    ``seed`` is an int or a sequence of ints (a dataset uses (dataset seed, frame index)); the same seed,
    camera and options give the same frame. ``camera`` defaults to the NYU preset (640x480).
    """
    camera = camera or Camera.preset("nyu")
    options = options or SceneOptions()
    entropy = seed_entropy(seed)
    layout_rng, view_rng, sensor_rng, rgb_rng = random_streams(entropy)
    world, position = build_world(layout_rng, options)
    soup, caster = world_caster(world, options)
    rotation = choose_view(
        caster, camera, position, soup, world, view_rng, options.pitch_deg, options.roll_sigma_deg
    )
    return render_view(world, soup, caster, camera, rotation, position, options, sensor_rng, rgb_rng, entropy)


def render_world(
    world: World,
    camera: Camera,
    rotation: np.ndarray,
    position: np.ndarray,
    options: SceneOptions | None = None,
    seed: int | Sequence[int] = 0,
) -> Scene:
    """Render a world built by hand from a given camera pose (camera-to-world ``rotation`` (3, 3), see
    :func:`cuboidcli.synth.view.look_rotation`, and ``position`` (3,), world metres, z up).

    ``seed`` drives the sensor noise and the colour noise (the same streams as :func:`generate_scene`).
    """
    options = options or SceneOptions()
    entropy = seed_entropy(seed)
    _, _, sensor_rng, rgb_rng = random_streams(entropy)
    soup, caster = world_caster(world, options)
    rotation, position = np.asarray(rotation, float), np.asarray(position, float)
    return render_view(world, soup, caster, camera, rotation, position, options, sensor_rng, rgb_rng, entropy)


def render_view(
    world, soup, caster, camera, rotation, position, options, sensor_rng, rgb_rng, entropy
) -> Scene:
    """One view of a built world: ray cast from the camera pose (``rotation`` (3, 3) camera-to-world,
    ``position`` (3,)), sensor depth, shading and the ground truth of what it sees; ``entropy`` is
    recorded as the frame's seed."""
    hits = caster.cast(camera, rotation, position)
    face = np.maximum(hits.face, 0)
    instances = np.where(hits.hit, soup.object_id[face], 0).astype(np.int32)
    part = np.where(hits.hit, soup.part[face], -1)
    part_px = np.bincount(part[part >= 0], minlength=len(world.parts))
    object_px = np.bincount(instances.ravel(), minlength=len(world.objects) + 1)
    depth = simulate_depth(hits.depth_m, hits.normal, camera, options.sensor, sensor_rng)
    shadow_caster = caster if options.shadows else None
    rgb = shade(hits, camera, rotation, position, soup, world, shadow_caster, rgb_rng, options.rgb_noise)
    cuboids = []
    for k, p in enumerate(world.parts):
        if part_px[k] == 0:
            continue  # the ground truth lists what the camera sees
        obj = world.object(p.object_id)
        tags = {"object": obj.id, "category": obj.category, "part": p.name, "visible_px": int(part_px[k])}
        cuboids.append(
            Cuboid(rotation.T @ (p.center - position), p.half_size, rotation.T @ p.rotation, extras=tags)
        )
    objects = [
        {"id": o.id, "category": o.category, "kind": o.kind, "visible_px": int(object_px[o.id])}
        for o in world.objects
        if object_px[o.id] > 0
    ]
    pose = np.eye(4)
    pose[:3, :3], pose[:3, 3] = rotation, position
    return Scene(camera, depth, hits.depth_m, rgb, instances, cuboids, objects, pose, entropy, world.room)

"""The synthetic world before rendering: box parts, non-box meshes, objects, materials and lights.

World frame: metres, z up, the floor at z = 0 (the camera frame only appears at render time). Every box part
is one ground-truth cuboid; objects group parts (a table is a top and four legs) and are the instances of
the instance image. Non-box clutter has an instance but no cuboid.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

#: Object kinds. "boxes": every visible surface lies on one of the object's cuboids; "mesh": clutter.
BOXES, MESH = "boxes", "mesh"


def rot_z(yaw: float) -> np.ndarray:
    """(3, 3) rotation about the world z axis by ``yaw`` radians."""
    c, s = np.cos(yaw), np.sin(yaw)
    return np.array([[c, -s, 0.0], [s, c, 0.0], [0.0, 0.0, 1.0]])


@dataclass
class Material:
    """Surface appearance. ``kind`` selects the procedural texture in :mod:`cuboidcli.synth.shading`.

    ``rgb`` / ``rgb2`` are linear albedos in [0, 1] (main and secondary colour, e.g. grain or grout);
    ``scale_m`` is the texture's feature size in metres; ``phase`` (4,) decorrelates objects of one kind.
    """

    kind: str
    rgb: np.ndarray
    rgb2: np.ndarray
    scale_m: float
    phase: np.ndarray


@dataclass
class BoxPart:
    """One box of an object, world frame: centre (3,), half-sizes (3,), rotation (3, 3) (axes as columns)."""

    object_id: int
    name: str
    center: np.ndarray
    half_size: np.ndarray
    rotation: np.ndarray
    material: int


@dataclass
class MeshPart:
    """A non-box surface: vertices (V, 3) world metres, faces (F, 3) indices, and the texture frame.

    ``frame`` = (rotation (3, 3), origin (3,)) so that textures stick to the object, not to the world.
    """

    object_id: int
    vertices: np.ndarray
    faces: np.ndarray
    material: int
    frame: tuple[np.ndarray, np.ndarray]


@dataclass
class ObjectInfo:
    """An instance: ``id`` >= 1 is its value in the instance image; ``kind`` is BOXES or MESH."""

    id: int
    category: str
    kind: str


@dataclass
class World:
    """Everything needed to render one frame (world frame, z up, metres)."""

    parts: list[BoxPart] = field(default_factory=list)
    meshes: list[MeshPart] = field(default_factory=list)
    objects: list[ObjectInfo] = field(default_factory=list)
    materials: list[Material] = field(default_factory=list)
    lights: list[tuple[np.ndarray, float]] = field(default_factory=list)
    """Point lights: (position (3,) m, intensity); intensity 1 lights a surface facing it 1 m away fully."""
    room: dict = field(default_factory=dict)
    """Room size and openings, for the record (``size_m`` (x, y, z), ``walls``, ``doorway``...)."""

    def new_object(self, category: str, kind: str = BOXES) -> int:
        oid = len(self.objects) + 1
        self.objects.append(ObjectInfo(oid, category, kind))
        return oid

    def add_material(self, material: Material) -> int:
        self.materials.append(material)
        return len(self.materials) - 1

    def add_box(self, object_id: int, name: str, center, half_size, rotation, material: int) -> BoxPart:
        part = BoxPart(
            object_id,
            name,
            np.asarray(center, float),
            np.abs(np.asarray(half_size, float)),
            np.asarray(rotation, float),
            material,
        )
        self.parts.append(part)
        return part

    def add_mesh(self, object_id: int, vertices, faces, material: int, frame) -> MeshPart:
        mesh = MeshPart(object_id, np.asarray(vertices, float), np.asarray(faces, np.int64), material, frame)
        self.meshes.append(mesh)
        return mesh

    def object(self, oid: int) -> ObjectInfo:
        return self.objects[oid - 1]

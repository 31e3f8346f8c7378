"""Procedural indoor RGB-D scenes with ground-truth cuboids (training data, tests, the demo sample).

A room (floor, ceiling, two to four walls, sometimes a doorway and a corridor) is furnished with box
assemblies (tables, desks, beds, cabinets, shelves, sofas, chairs, boxes, wall cupboards, door frames),
small objects on their surfaces and non-box clutter (cylinders, spheres, cones, low-poly blobs). A
camera placed inside renders exact depth with open3d's ray caster; a Kinect-like sensor model adds noise
and holes; a simple shader paints the RGB image. Every box part is a ground-truth cuboid in the camera
frame, tagged with its object, category and part.

Public entry points:

- :func:`generate_scene` — one frame as a :class:`Scene` (arrays and cuboids).
- :func:`write_dataset` — many frames in the generic dataset layout (``cuboids synth``).
- :func:`render_boxes` — exact depth and instance images of given cuboids (for render-then-fit tests).
- :func:`render_world` — render a world composed by hand (as ``scripts/make_sample.py`` does).
"""

from cuboidcli.synth.dataset import frame_name, split_of, write_dataset, write_frame
from cuboidcli.synth.render import render_boxes
from cuboidcli.synth.scene import Scene, SceneOptions, generate_scene, render_world
from cuboidcli.synth.sensor import SensorOptions

__all__ = [
    "Scene",
    "SceneOptions",
    "SensorOptions",
    "frame_name",
    "generate_scene",
    "render_boxes",
    "render_world",
    "split_of",
    "write_dataset",
    "write_frame",
]

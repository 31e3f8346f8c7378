"""One input: whatever ``cuboids fit`` and :meth:`cuboidcli.api.Fitter.fit` take, read into one
:class:`Input`, whose :meth:`Input.fit_input` is the estimator's
:class:`~cuboidcli.fitting.fit_input.FitInput`.

- a frame (:mod:`cuboidcli.load.frame`): a depth map file with its camera (and a photo beside it), a
  photo alone (depth from RGB), a depth array with a :class:`~cuboidcli.camera.Camera`; fitted in the
  camera's OpenCV frame;
- a room (:mod:`cuboidcli.load.room`): a point cloud or mesh file, a posed RGB-D sequence folder, an
  (N, 3[+3]) array or an Open3D point cloud; fitted in its own world frame.

How to read it (``-K``, ``--camera``, ``--depth-scale``, ``--unit``, ``--every``, the depth model) is one
:class:`LoadOptions`; an option that does not apply to the input is refused (:func:`refused_options`).
"""

from __future__ import annotations

from dataclasses import dataclass, field, fields
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.io.depth import InputError

if TYPE_CHECKING:
    from cuboidcli.factories import DepthModelOptions
    from cuboidcli.geometry.vanishing import LineEstimate

#: What an input is, by how it is read: a depth map, a photo (depth from RGB), a scan file, a sequence
#: folder, points in memory. The first two are frames, the others rooms.
SOURCES = {"depth": "frame", "photo": "frame", "scan": "room", "sequence": "room", "points": "room"}


@dataclass(frozen=True)
class LoadOptions:
    """How to read an input. Frozen and picklable: a folder's job sends it to its workers."""

    intrinsics: str | None = None
    """``-K``: fx,fy,cx,cy in pixels or a JSON file (one camera, or one per frame name)."""
    camera: str | None = None
    """``--camera``: a preset (nyu, tum, scannet): intrinsics and depth scale."""
    depth_scale: float | None = None
    """``--depth-scale``: metres per depth-PNG unit (None: the intrinsics', the preset's, else 0.001)."""
    unit: str = "m"
    """``--unit``: a point cloud's or mesh's unit (m, cm, mm)."""
    every: int = 1
    """``--every``: a sequence fuses every n-th frame."""
    depth_model: DepthModelOptions | None = None
    """A photo's depth model (None: the built-in network)."""

    def to_dict(self, source: str) -> dict:
        """The options that applied to an input of ``source`` (:data:`SOURCES`), for its ``settings``."""
        import json
        from dataclasses import asdict, is_dataclass

        out = {}
        for name in APPLIES:
            if source in APPLIES[name]:
                value = getattr(self, name)
                out[name] = asdict(value) if is_dataclass(value) else value
        if isinstance(out.get("depth_model"), dict):  # where it ran is the fit's device setting
            out["depth_model"].pop("device", None)
        return json.loads(json.dumps(out))  # as a saved result holds it (tuples as lists)


#: Which sources each option applies to; given for another it is refused (one line, exit 2).
APPLIES: dict[str, tuple[str, ...]] = {
    "intrinsics": ("depth", "photo", "sequence"),
    "camera": ("depth", "photo", "sequence"),
    "depth_scale": ("depth", "photo", "sequence"),
    "unit": ("scan",),
    "every": ("sequence",),
    "depth_model": ("photo",),
}


def refused_options(options: LoadOptions, source: str) -> list[str]:
    """The options set to other than their default that an input of ``source`` does not read."""
    default = LoadOptions()
    return [
        f.name
        for f in fields(LoadOptions)
        if getattr(options, f.name) != getattr(default, f.name) and source not in APPLIES[f.name]
    ]


@dataclass
class View:
    """A frame of a sequence a room's overlay can be drawn on (its depth camera is the result's)."""

    name: str
    world_from_camera: np.ndarray
    depth_path: Path
    rgb_path: Path | None
    depth_scale: float


@dataclass
class Input:
    """One input, read: a frame or a room, with what its outputs need and its ``input`` record."""

    source: str
    """depth, photo, scan, sequence or points (:data:`SOURCES`)."""
    camera: Camera | None
    """A frame's camera, a sequence's depth camera; None for a bare cloud."""
    meta: dict
    """The result's ``input`` entry."""
    notes: list[str] = field(default_factory=list)
    """One-line warnings about the input."""
    depth_m: np.ndarray | None = None
    """A frame: (H, W) float32 metres, 0 = missing."""
    rgb: np.ndarray | None = None
    """A frame's image (H, W, 3) uint8, if any."""
    depth_seconds: float | None = None
    """A photo: seconds the depth estimation took (part of the fit's time)."""
    room: object = None
    """A room: :class:`cuboidcli.load.room.RoomData` (points, colours, viewpoints, up hint, sequence)."""
    lines: LineEstimate | None = None
    """A frame with a photo: what its lines say (down, focal length, room axes) in ``camera``'s frame,
    the fit's prior on its down direction (:func:`cuboidcli.geometry.down.combine_down`)."""
    lines_seconds: float | None = None
    """Seconds finding the photo's lines took (part of the fit's time); None: no photo was read."""

    @property
    def kind(self) -> str:
        """``frame`` or ``room``."""
        return SOURCES[self.source]

    @property
    def frame(self) -> str:
        """The result's coordinate frame: ``opencv`` (a frame's camera) or ``world`` (a room's own)."""
        return "opencv" if self.kind == "frame" else "world"

    @property
    def points(self) -> np.ndarray | None:
        """A room's input points (N, 3) metres in its world frame."""
        return None if self.room is None else self.room.cloud.points

    @property
    def views(self) -> list[View]:
        """The frames of a sequence a room's overlays can be drawn on; empty otherwise."""
        seq = None if self.room is None else self.room.sequence
        if seq is None:
            return []
        return [
            View(f.name, f.world_from_camera, f.depth_path, f.rgb_path, seq.depth_scale) for f in seq.frames
        ]

    def fit_input(self, config):
        """The estimator's :class:`~cuboidcli.fitting.fit_input.FitInput` under ``config`` (a FitConfig
        for this input's kind): a frame's grid, or a room's voxels, up and visibility."""
        if self.kind == "frame":
            from cuboidcli.fitting.prepare import frame_input

            return frame_input(
                self.depth_m, self.camera, config, lines=self.lines, depth_predicted=self.source == "photo"
            )
        from cuboidcli.fitting.room import room_input

        cloud = self.room.cloud
        return room_input(cloud.points, config, cloud.viewpoints, self.room.up_hint, cloud.colors)


def source_of(x, camera: Camera | None = None) -> str:
    """What kind of input ``x`` is (:data:`SOURCES`): a depth array with a camera, points in memory, a
    sequence folder, a scan file, a photo or a depth map file. Raises InputError for what is none."""
    from cuboidcli.load.room import is_room_input

    if isinstance(x, np.ndarray) or hasattr(x, "points"):
        if camera is not None:
            return "depth"
        arr = np.asarray(x) if isinstance(x, np.ndarray) else None
        if arr is not None and not (arr.ndim == 2 and arr.shape[1] in (3, 6)):
            raise InputError(
                f"an array of shape {arr.shape}: give a depth map (H, W) with its camera, or points (N, 3)"
            )
        return "points"
    p = Path(x)
    if not p.exists():
        raise InputError(f"not found: {p}")
    if p.is_dir():
        if is_room_input(p):
            return "sequence"
        raise InputError(
            f"{p} is a folder but not an RGB-D sequence; fit a folder of frames with cuboids fit"
        )
    if is_room_input(p):
        return "scan"
    from cuboidcli.io.inputs import IMAGE_SUFFIXES, is_colour_image

    if p.suffix.lower() in IMAGE_SUFFIXES and is_colour_image(p):
        return "photo"
    return "depth"


def load(
    x,
    options: LoadOptions | None = None,
    *,
    camera: Camera | None = None,
    image: str | Path | None = None,
    rgb: np.ndarray | None = None,
    source: str | None = None,
    progress=None,
) -> Input:
    """Read ``x`` as one :class:`Input`: a depth map file (``image``: its photo), a photo, a scan file, a
        sequence folder, a depth array (H, W) metres with ``camera`` (``rgb``: its image), points (N, 3[+3])
        or an Open3D point cloud. ``source`` says which when the caller knows (``--depth`` is a depth map);
    None: :func:`source_of`. ``progress(done, total)`` follows a sequence's fusion. Raises InputError
        (one line) for unusable input or an option that does not apply to it."""
    from cuboidcli.load import frame, room

    options = options or LoadOptions()
    source = source or source_of(x, camera)
    refused = refused_options(options, source)
    if refused:
        names = ", ".join(f"--{n.replace('_', '-')}" for n in refused)
        raise InputError(f"{names} does not apply to {_describe(source)}; leave it out")
    if source == "depth" and camera is not None:
        f = frame.array_frame(x, camera, rgb)
        return Input(source, f.camera, f.meta, f.notes, f.depth_m, f.rgb)
    if source in ("depth", "photo"):
        depth, photo = (x, image) if source == "depth" else (None, x)
        f = frame.load_frame(
            depth, photo, options.intrinsics, options.camera, options.depth_scale,
            depth_model=options.depth_model,
        )  # fmt: skip
        return Input(
            source, f.camera, f.meta, f.notes, f.depth_m, f.rgb, f.depth_seconds,
            lines=f.lines, lines_seconds=f.lines_seconds,
        )  # fmt: skip
    if source == "points":
        data = room.points_room(x)
    else:
        data = room.load_room(
            x, unit=options.unit, every=options.every, intrinsics=options.intrinsics or options.camera,
            depth_scale=options.depth_scale, progress=progress,
        )  # fmt: skip
    return Input(source, data.camera, data.meta, list(data.cloud.warnings), room=data)


def _describe(source: str) -> str:
    return {
        "depth": "a depth map",
        "photo": "a photo",
        "scan": "a point cloud or mesh",
        "sequence": "an RGB-D sequence",
        "points": "points in memory",
    }[source]


__all__ = ["APPLIES", "Input", "LoadOptions", "SOURCES", "View", "load", "refused_options"]

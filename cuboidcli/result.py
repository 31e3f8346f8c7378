"""One fitted input, a frame's or a room's: :class:`Result` holds the "cuboids/1" record (its ``frame`` is
the camera's OpenCV frame or the room's world frame), what happened while fitting, and the data its outputs
are drawn from; :meth:`Result.save` writes the JSON and the outputs asked for through one writer,
:func:`cuboidcli.export.write`."""

from __future__ import annotations

import os
from dataclasses import dataclass
from functools import cached_property
from pathlib import Path

import numpy as np

from cuboidcli.camera import Camera
from cuboidcli.cuboid import Cuboid
from cuboidcli.io.result import FitResult, fit_info_record, settings_record
from cuboidcli.load import Input


def result_record(
    inp: Input, cuboids: list[Cuboid], info, config, solver_name: str, sampler_name: str, extra: dict
) -> FitResult:
    """The "cuboids/1" record of a fitted input: a frame's in its camera's frame, a room's in its own world
    frame (``frame`` "world", with its up direction, levelled world, whole objects and, for a sequence,
    the frames that saw each cuboid). ``info`` is the fit's FitInfo, ``config`` its resolved FitConfig,
    ``extra`` settings beside the config's (weights, how the input was read)."""
    from cuboidcli.load.room import seen_by, world_from_input

    settings = settings_record(config, info, solver_name, sampler_name, extra)
    extras: dict = {"fit_info": fit_info_record(info)}
    if inp.kind == "frame":
        if info.gravity is not None:
            extras["gravity"] = info.gravity.to_dict()
            extras["world_from_camera"] = info.gravity.world_from_camera().tolist()
        return FitResult(inp.camera, cuboids, settings, info.timing_s, inp.meta, extras)
    room = inp.room
    out = []
    names = seen_by(room.cloud, info.point_labels, len(cuboids))
    for c, seen in zip(cuboids, names, strict=True):
        more = dict(c.extras)
        if room.sequence is not None:
            more["frames"] = seen
        out.append(Cuboid(c.center, c.half_size, c.rotation, c.inlier_gain, more, c.kind))
    up = info.room_up
    extras.update(
        up=up.to_dict(),
        gravity={"down": [round(-float(v), 6) for v in up.up], "source": up.source},
        world_from_input=world_from_input(up.up, up.axes).tolist(),
        objects=[o.to_dict(i) for i, o in enumerate(info.objects)],
    )
    if room.sequence is not None:
        extras["frames"] = [
            {"name": f.name, "world_from_camera": f.world_from_camera.tolist()} for f in room.sequence.frames
        ]
    timing = {"load": round(room.load_seconds, 6), **info.timing_s}
    return FitResult(inp.camera, out, settings, timing, inp.meta, extras, frame="world")


def objects_summary(objects) -> str:
    """A room's objects in words: ``55 objects (3 doors, 1 sink)``, the doors and sinks among them counted
    (``objects``: the fit's :class:`~cuboidcli.fitting.objects.SceneObject` list)."""
    kinds = [o.kind for o in objects]
    named = [f"{kinds.count(k)} {k}{'s' * (kinds.count(k) != 1)}" for k in ("door", "sink") if k in kinds]
    return f"{len(kinds)} object{'s' * (len(kinds) != 1)}" + (f" ({', '.join(named)})" if named else "")


@dataclass(repr=False)
class Result:
    """One fitted frame or room: the cuboids, how they were found, and the data the outputs are made from.

    ``record`` is the "cuboids/1" content (what ``cuboids fit`` writes), ``info`` what happened while fitting
    (:class:`~cuboidcli.fitting.pipeline.FitInfo`: per-cuboid gains, Theta, steps, stop reason, per-stage
    seconds; a room's up, voxels and objects), ``input`` the :class:`~cuboidcli.load.Input` that was fitted.
    """

    record: FitResult
    info: object
    input: Input

    @property
    def kind(self) -> str:
        """``frame`` or ``room``."""
        return self.input.kind

    @property
    def cuboids(self) -> list[Cuboid]:
        """The cuboids in selection order, in the result's frame (a frame's OpenCV camera frame, a room's
        own), metres, each with its ``kind`` and ``inlier_gain``."""
        return self.record.cuboids

    @property
    def camera(self) -> Camera | None:
        return self.record.camera

    @property
    def settings(self) -> dict:
        """The resolved configuration (FitConfig fields, Theta used, solver, sampler, weights, loading)."""
        return self.record.settings

    @property
    def depth_m(self) -> np.ndarray | None:
        """A frame's fitted depth map (H, W) metres; None for a room."""
        return self.input.depth_m

    @property
    def rgb(self) -> np.ndarray | None:
        return self.input.rgb

    @property
    def points(self) -> np.ndarray | None:
        """A room's input points (N, 3) in its world frame; None for a frame."""
        return self.input.points

    @property
    def point_labels(self) -> np.ndarray | None:
        """A room: (N,) int32 per input point, the cuboid it is an inlier of (-1 none, -2 hidden)."""
        return self.info.point_labels

    @property
    def objects(self) -> list[Cuboid]:
        """A room's whole objects as upright boxes (a table with its legs), largest first;
        ``extras["cuboids"]`` holds the indices of the cuboids each is made of, ``extras["kind"]`` what it is
        (``object``, ``door`` or ``sink``). Empty for a frame."""
        return [
            Cuboid(
                o.box.center,
                o.box.half_size,
                o.box.rotation,
                extras={"cuboids": list(o.cuboids), "kind": o.kind},
            )
            for o in self.info.objects
        ]

    @property
    def up(self) -> np.ndarray | None:
        """(3,) the up direction in the result's frame, None when unknown: a room's as estimated, a frame's
        as its record holds it (what a saved result levels its scene files by, too)."""
        if self.info.room_up is not None:
            return self.info.room_up.up
        from cuboidcli.export.fitted import result_up

        return result_up(self.record)

    @property
    def views(self) -> list:
        """The frames of a sequence a room's overlays are drawn on (:class:`cuboidcli.load.View`)."""
        return self.input.views

    @property
    def grid_labels(self) -> np.ndarray | None:
        """A frame: (ceil(H / s), ceil(W / s)) int32 over the fitting grid (step s = ``info.grid_step``), as
        counted while fitting: k >= 0 inlier of cuboid k, -1 none, -2 hidden behind a cuboid, -3 no depth."""
        return self.info.assignment

    @cached_property
    def labels(self) -> np.ndarray:
        """A frame: (H, W) int32 per pixel: k >= 0 inlier of cuboid k, -1 none, -2 hidden behind a cuboid,
        -3 no depth, with the fit's own tau, beta and occlusion setting. A room: its ``point_labels``."""
        if self.kind == "room":
            return self.point_labels
        from cuboidcli.export.ply import assign_labels, depth_points

        h, w = self.depth_m.shape
        labels = np.full(h * w, -3, dtype=np.int32)
        points, pix = depth_points(self.depth_m, self.camera)
        labels[pix] = assign_labels(points, self.cuboids, self.settings)
        return labels.reshape(h, w)

    def to_json(self) -> dict:
        """The "cuboids/1" document (README, "Output schema")."""
        return self.record.to_json()

    def save_json(self, path: str | os.PathLike) -> Path:
        """Write the "cuboids/1" JSON, atomically."""
        from cuboidcli.io.result import write_result

        return write_result(path, self.record)

    def overlay(self, rgb: np.ndarray | None = None) -> np.ndarray:
        """A frame: (H, W, 3) uint8, the cuboids drawn over ``rgb`` (default: the frame's image, else its
        coloured depth), z-buffered against each other."""
        if self.kind != "frame":
            raise ValueError(
                "an overlay is drawn over a frame; a room's are drawn on its views (save overlay)"
            )
        from cuboidcli.export.overlay import background_image, draw_overlay

        rgb = self.rgb if rgb is None else rgb
        background = background_image(self.camera, rgb, None if rgb is not None else self.depth_m)
        return draw_overlay(background, self.camera, self.cuboids)

    def save(
        self, json_path: str | os.PathLike, kinds: tuple[str, ...] = (), *, with_points: bool = False
    ) -> list[Path]:
        """The JSON and, beside it, the outputs of ``kinds`` (:data:`cuboidcli.export.OUTPUTS`: ``"glb"``,
        ``"ply"``, ``"overlay"``, ``"html"``, ...; ``with_points`` adds the points to the GLB).

        The JSON is written last (each file atomically): where it exists, the outputs are complete.
        Returns the paths, the JSON first."""
        from cuboidcli.export import write
        from cuboidcli.export.files import result_stem

        def json() -> dict[str, Path]:
            return {"json": self.save_json(json_path)}

        # one call for every file, so that a folder that fills up or is read-only leaves none of them
        written = write(
            self, result_stem(json_path), tuple(kinds), with_points=with_points, last=(json_path, json)
        )
        return [written.pop("json"), *written.values()]

    def __repr__(self) -> str:
        kinds = sorted({c.kind for c in self.cuboids})
        objects = f"; {objects_summary(self.info.objects)}" if self.kind == "room" else ""
        return (
            f"Result({len(self.cuboids)} cuboids: {', '.join(kinds) or 'none'}{objects}; "
            f"{self.info.n_points} points, stop: {self.info.stop_reason}, "
            f"{self.record.timing_s.get('total', 0.0):.2f} s)"
        )

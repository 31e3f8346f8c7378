"""Where a frame's camera comes from, decided in one place.

In this order: ``-K`` (``fx,fy,cx,cy`` or a JSON file) or ``--camera`` (a preset, scaled to an image of the
same aspect ratio), the photo's EXIF, the photo's lines (the focal length of its vanishing points, when
their ``focal_confidence`` reaches :data:`FOCAL_SURE`), a depth model that predicts the focal length, else
a default field of view (with a warning), unless the lines, unsure, still rule out its focal length: then
theirs (with a warning). The camera's ``source`` says which; the result records it
(``input.intrinsics_source``). The metres per depth-PNG unit follow the same order: ``--depth-scale``,
the intrinsics file, the preset, millimetres.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from cuboidcli.camera import PRESETS, Camera
from cuboidcli.io.depth import InputError, intrinsics_for_size, parse_intrinsics
from cuboidcli.io.photo import DEFAULT_FOV_DEG, centred_intrinsics, default_camera

if TYPE_CHECKING:
    from cuboidcli.geometry.vanishing import LineEstimate

__all__ = ["DEFAULT_FOV_DEG", "centred_intrinsics", "default_camera", "given_camera", "guessed_note"]

#: The lines' ``focal_confidence`` from which their focal length is the camera's. Chosen on the 11 real
#: photos of ../shared/data and their 480x360 centre crops (scripts/eval_photo_lines.py): the 8 of 22
#: estimates at 0.25 or more are all within 4 % of the true fx; the most confident wrong one (the NYU
#: living room's crop, facing its wall, 31 % short) has 0.15.
FOCAL_SURE = 0.25

#: Stands in for "no intrinsics given" where only their depth scale is asked for.
_NO_INTRINSICS = Camera(0.0, 0.0, 0.0, 0.0)


def check_preset(preset: str | None) -> None:
    """InputError naming the presets when ``preset`` is not one."""
    if preset is not None and preset not in PRESETS:
        raise InputError(f"unknown --camera {preset!r}; choose one of: {', '.join(PRESETS)}")


def given_camera(intrinsics: str | None, preset: str | None, frame: str | None = None) -> Camera | None:
    """The camera the user gave: ``-K`` (``intrinsics``; a JSON file may hold one entry per ``frame``
    name) or ``--camera`` (``preset``), not yet sized to the image; None when neither was given."""
    check_preset(preset)
    return parse_intrinsics(intrinsics, preset, frame=frame) if intrinsics or preset else None


def sized(given: Camera, width: int, height: int, intrinsics: str | None, preset: str | None) -> Camera:
    """The given camera for a ``width`` x ``height`` image: a preset is scaled to an image of its aspect
    ratio; ``-K`` must describe the image as it is."""
    return intrinsics_for_size(given, width, height, None if intrinsics else preset)


def resolve_depth_scale(depth_scale: float | None, given: Camera | None, preset: str | None) -> float:
    """Metres per depth-PNG unit: ``--depth-scale`` > the intrinsics file's > the preset's > millimetres."""
    if depth_scale is not None:
        if depth_scale <= 0:
            raise InputError(f"--depth-scale must be positive (got {depth_scale})")
        return depth_scale
    if (given or _NO_INTRINSICS).depth_scale is not None:
        return given.depth_scale
    if preset is not None:
        return float(PRESETS[preset]["depth_scale"])
    return 0.001


def guessed_note(camera: Camera) -> str:
    """The warning when no source said anything about the lens and the default field of view is assumed."""
    return (
        f"no camera intrinsics (no -K, --camera or EXIF focal length): assuming a {DEFAULT_FOV_DEG:g} degree "
        f"field of view across the long side (fx = {camera.fx:.1f} px); pass -K fx,fy,cx,cy for exact boxes"
    )


def default_for(width: int, height: int, notes: list[str], lines: LineEstimate | None = None) -> Camera:
    """The default field of view's camera, with its warning added to ``notes``; unless the photo's
    ``lines``, unsure of their focal length, still rule out the default's
    (:meth:`~cuboidcli.geometry.vanishing.LineEstimate.rules_out`: a cropped or zoomed photo): then the
    lines' focal length, with a warning that says so."""
    camera = default_camera(width, height)
    if lines is not None and lines.focal_px is not None and lines.rules_out(camera.fx):
        source = (
            f"photo lines (focal confidence {lines.focal_confidence:.2f}; they rule out the default "
            f"{DEFAULT_FOV_DEG:g} degree field of view)"
        )
        notes.append(
            "no camera intrinsics (no -K, --camera or EXIF focal length): the photo's lines are unsure of "
            f"the focal length (fx = {lines.focal_px:.1f} px, confidence {lines.focal_confidence:.2f}) but "
            f"fit the default {DEFAULT_FOV_DEG:g} degree field of view (fx = {camera.fx:.1f} px) worse, so "
            "theirs is used; pass -K fx,fy,cx,cy for exact boxes"
        )
        return centred_intrinsics(lines.focal_px, width, height, source)
    notes.append(guessed_note(camera))
    return camera


def from_focal(focal_px: float, width: int, height: int, source: str) -> Camera:
    """A depth model's predicted focal length as the camera (principal point at the image centre)."""
    return centred_intrinsics(focal_px, width, height, source)


def from_lines(lines: LineEstimate | None, width: int, height: int) -> Camera | None:
    """The focal length of a photo's vanishing points as the camera (principal point at the image centre,
    where the lines put it) when they fix it surely (:data:`FOCAL_SURE`); None otherwise."""
    if lines is None or lines.focal_px is None or lines.focal_confidence < FOCAL_SURE:
        return None
    source = f"photo lines (focal confidence {lines.focal_confidence:.2f})"
    return centred_intrinsics(lines.focal_px, width, height, source)

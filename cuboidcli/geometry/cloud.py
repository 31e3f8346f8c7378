"""Unorganised points (a scanned or fused room, in its own world frame): voxel down-sampling, surface
normals, and the room's up direction and Manhattan axes.

A frame finds gravity from its image grid and the camera's own up (:mod:`cuboidcli.geometry.gravity`).
A room has neither: normals come from each point's neighbours in space, and the up axis is the axis of the
room's Manhattan frame whose floor is the clearest: the lowest large plane facing along it, with the cloud
a room's height above it (:func:`floor_scores`). Where two directions are near alike (a scan fragment of a
wall and a ceiling strip looks the same turned on its side) a hint decides: the cameras' mean up for a
sequence, a camera's -y for a depth image in its frame, the file format's convention for other clouds (z
up, y up for glTF).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from cuboidcli.geometry.gravity import manhattan_axes, manhattan_frame, refine_frame
from cuboidcli.geometry.normals import estimate_normals_pca


def voxel_groups(points: np.ndarray, voxel_m: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Group points (N, 3) by cubic voxels of side ``voxel_m``: (mean point of each voxel (M, 3) float64,
    voxel of each point (N,) int64, first point of each voxel in input order (M,) int64). Voxels are
    ordered by their integer coordinates, so the result does not depend on the order of the input."""
    p = np.asarray(points, dtype=np.float64)
    cell = np.floor((p - p.min(0)) / voxel_m).astype(np.int64)
    dims = cell.max(0) + 1
    key = (cell[:, 0] * dims[1] + cell[:, 1]) * dims[2] + cell[:, 2]
    _, first, inverse, counts = np.unique(key, return_index=True, return_inverse=True, return_counts=True)
    inverse = inverse.ravel()
    sums = np.zeros((len(first), 3))
    np.add.at(sums, inverse, p)
    return sums / counts[:, None], inverse, first


def estimate_normals(points: np.ndarray, radius_m: float, max_nn: int = 24) -> np.ndarray:
    """Unit surface normals (N, 3) of points (N, 3) from their neighbours within ``radius_m`` (at most
    ``max_nn``, the nearest) by local PCA (:mod:`cuboidcli.geometry.normals`; the same normals as Open3D's
    ``estimate_normals`` without importing it); zeros where fewer than 3 neighbours lie that close; signs are
    arbitrary (the Manhattan frame ignores them)."""
    return estimate_normals_pca(points, radius_m, max_nn)


#: A plane is the floor candidate of a direction when it lies in this lowest share of the points' extent.
FLOOR_BAND = 0.15
#: ... and holds at least this share of the points (with normals along the direction).
FLOOR_MIN_SHARE = 0.01
#: Extents along up (floor to the highest point, m) that are a room's: full plausibility inside, none at
#: the first and below, falling as 1 / extent squared above the last.
ROOM_HEIGHT_M = (0.6, 1.8, 4.0)
#: The cloud's evidence overrides the hint only when its best direction scores this many times the hint's,
#: and is sure of it (its confidence at least :data:`UNSURE`): a synthetic room seen by 8 views scored two
#: walls' axes 0.22 and 0.18 against its floor's 0.03 (too little of it seen) and was fitted on its side,
#: 1.5 degrees from its cameras' up; the real living-room fragment, stored with y down, scores its floor
#: 0.40 clear of every other axis.
HINT_TIE = 2.0
#: Below this confidence the up direction comes with a warning.
UNSURE = 0.25
#: Below this confidence the best axis is in a tie with another one: unsure whichever the hint picks.
TIE = 0.05
#: A room scan stored above z = 0.1 m, seen from an origin below or beside it, passes for a camera's view
#: (:func:`is_camera_view`: too few points on each ray to hide each other). Its file's own up then wins
#: over the camera's -y when it scores a floor of at least this (ScanNet scans: 0.08-0.19, their -y 0-0.09)
#: and above the camera's (a depth image of a wall, a ceiling strip and a sofa: 0.01; the living-room
#: fragment, kept in its first camera's frame: 0).
OWN_FLOOR = 0.05
#: A file's convention is wrong more often than a camera: a room stored y up is read as z up. An axis across
#: the convention's (perpendicular to it) then wins without a clear score when its floor is open above: its
#: score less its opposite's (a scan's floor has no ceiling over it; a wall faces the opposite wall) is at
#: least :data:`OPEN_FLOOR`, more than the convention's axis's, and its score at least :data:`OPEN_SHARE` of
#: that axis's. The 10 real ScanNet scans turned y up, y down and x up: such a floor's margin is 0.079-0.202,
#: a wall's at most 0.100 and less than the floor's; the synthetic rooms (bare, with ceilings) give their
#: walls at most 0.091, below their own floor's margin or their score far below the floor's.
OPEN_FLOOR = 0.07
OPEN_SHARE = 0.8


@dataclass(frozen=True)
class RoomUp:
    """The up direction of a room and how it was found."""

    up: np.ndarray
    """(3,) unit, in the input's world frame."""
    axes: np.ndarray | None
    """(3, 3) the room's Manhattan axes (columns: up, two horizontal), or None when none was found."""
    source: str
    """"given", "estimated" (from the cloud's floor and Manhattan frame, the hint breaking near ties),
    "camera" (a depth image in a camera's frame: its -y) or "hint" (the hint as it is)."""
    support: tuple[float, float, float] = (0.0, 0.0, 0.0)
    """Share of the normals along each column of ``axes``."""
    confidence: float = 1.0
    """In [0, 1]: how much the chosen direction's floor evidence exceeds the next direction's (1 - the ratio
    of their scores, :func:`floor_scores`, or of their margins over the opposite direction for a floor
    open above: :func:`_confidence`); 1 when given."""
    warning: str = ""
    """One line for the user when the direction is unsure, else empty."""

    def to_dict(self) -> dict:
        out = {"up": [round(float(v), 6) for v in self.up], "source": self.source}
        out["confidence"] = round(float(self.confidence), 4)
        if self.warning:
            out["warning"] = self.warning
        if self.axes is not None:
            out["manhattan_frame"] = [[round(float(v), 6) for v in row] for row in self.axes]
            out["support"] = [round(float(s), 4) for s in self.support]
        return out


def settle_axis(normals: np.ndarray, axis: np.ndarray, angles_deg=(25.0, 15.0, 8.0)) -> np.ndarray:
    """(3,) ``axis`` moved to the mean of the normals (N, 3; either sign) around it, in shrinking cones: the
    densest direction of the surfaces facing along it. The Manhattan frame is a compromise of three axes
    (walls that are not quite perpendicular tilt it); each of its axes settles on its own surfaces."""
    axis = np.asarray(axis, dtype=np.float64)
    for angle in angles_deg:
        dots = normals @ axis
        sel = np.abs(dots) > np.cos(np.deg2rad(angle))
        if sel.sum() < 20:
            break
        mean = (normals[sel] * np.sign(dots[sel])[:, None]).sum(0)
        axis = mean / np.linalg.norm(mean)
    return axis


def floor_normal(points: np.ndarray, normals: np.ndarray, up: np.ndarray, rounds: int = 3) -> np.ndarray:
    """(3,) ``up`` made the normal of its floor: the plane through the points (N, 3) within 3 cm of the
    lowest large plane facing along it (:func:`floor_scores`' floor), fitted by least squares (the smallest
    principal axis), twice more on the points of the refitted plane; ``up`` when there is no such plane."""
    up = np.asarray(up, dtype=np.float64)
    for _ in range(rounds):
        h = points @ up
        lo, hi = np.percentile(h, [1.0, 99.0])
        facing = (np.abs(normals @ up) > np.cos(np.deg2rad(15.0))) & (h < lo + FLOOR_BAND * (hi - lo))
        if facing.sum() < max(20, FLOOR_MIN_SHARE * len(points)):
            return up
        base = h[facing].min()
        slices = np.bincount(np.floor((h[facing] - base) / 0.03).astype(np.int64))
        level = base + 0.03 * (int(np.convolve(slices, np.ones(3), mode="same").argmax()) + 0.5)
        near = points[np.abs(h - level) < 0.03]
        if len(near) < 20:
            return up
        d = near - near.mean(0)
        normal = np.linalg.eigh(d.T @ d)[1][:, 0]
        if abs(float(normal @ up)) < np.cos(np.deg2rad(15.0)):
            return up  # the slice is not one plane facing along up
        up = normal * np.sign(normal @ up)
    return up


def floor_scores(points: np.ndarray, normals: np.ndarray, frame: np.ndarray) -> np.ndarray:
    """(6,) how much each signed axis of ``frame`` (3, 3), in the order +a0, -a0, +a1, -a1, +a2, -a2, looks
    like up: the share of the points on its floor times the room-height plausibility of the extent.

    The floor of a direction u is the largest plane facing along u (normals within 15 degrees, 3 cm slices
    of the heights p . u) in the lowest :data:`FLOOR_BAND` of the points' extent, when it holds at least
    :data:`FLOOR_MIN_SHARE` of them: the lowest large horizontal surface, with everything above it. The
    extent (1st to 99th percentile of the heights) is a room's height between 1.8 and 4 m; a direction
    along which the cloud is thinner than a room is high (linearly down to 0.6 m), or longer (as the
    square of 4 m over the extent: two rooms' walls seen through a door are not a floor), is less likely
    up (:data:`ROOM_HEIGHT_M`). Each axis first settles on its own surfaces (:func:`settle_axis`)."""
    out = np.zeros(6)
    lo_m, full_m, hi_m = ROOM_HEIGHT_M
    for k in range(3):
        axis = settle_axis(normals, frame[:, k])
        facing = np.abs(normals @ axis) > np.cos(np.deg2rad(15.0))
        for s, sign in enumerate((1.0, -1.0)):
            h = points @ (sign * axis)
            lo, hi = np.percentile(h, [1.0, 99.0])
            extent = hi - lo
            low = facing & (h < lo + FLOOR_BAND * extent)
            if low.sum() < FLOOR_MIN_SHARE * len(points) or extent <= 0:
                continue
            slices = np.bincount(np.floor((h[low] - h[low].min()) / 0.03).astype(np.int64))
            plane = np.convolve(slices, np.ones(3), mode="same").max() / len(points)
            if plane < FLOOR_MIN_SHARE:
                continue
            height = np.clip((extent - lo_m) / (full_m - lo_m), 0.0, 1.0) * min(1.0, hi_m / extent) ** 2
            out[2 * k + s] = plane * height
    return out


def is_camera_view(points: np.ndarray, cell_rad: float = 0.01, gap_m: float = 0.1) -> bool:
    """Whether points (N, 3) are a depth image in a camera's frame (OpenCV, PCL, Open3D: x right, y down, z
    forward): every point lies in front of the origin (z > 0.1 m) and at least 80 % of them are the
    nearest surface along their ray from it (cells of ``cell_rad`` in x / z and y / z; a point more than
    ``gap_m`` behind its cell's nearest is hidden). A room scanned from inside and stored in its own frame
    has points all around the origin or behind each other along its rays; one stored above z = 0.1 m and
    seen from below spreads its points over so many rays that it can pass (:func:`room_up` then asks its
    floor, :data:`OWN_FLOOR`)."""
    p = np.asarray(points, dtype=np.float64)
    if len(p) == 0 or not np.all(p[:, 2] > 0.1):
        return False
    u = np.floor(p[:, 0] / p[:, 2] / cell_rad).astype(np.int64)
    v = np.floor(p[:, 1] / p[:, 2] / cell_rad).astype(np.int64)
    key = (u - u.min()) * (v.max() - v.min() + 1) + (v - v.min())
    depth = np.linalg.norm(p, axis=1)
    order = np.lexsort((depth, key))
    key, depth = key[order], depth[order]
    first = np.r_[True, key[1:] != key[:-1]]
    nearest = depth[np.maximum.accumulate(np.where(first, np.arange(len(key)), 0))]
    return float(np.mean(depth - nearest <= gap_m)) >= 0.8


def room_up(
    points: np.ndarray,
    normals: np.ndarray,
    hint: np.ndarray,
    given: np.ndarray | None = None,
    seed: int = 0,
    min_support: float = 0.05,
    cameras: bool = False,
) -> RoomUp:
    """The room's up direction and axes from points (N, 3) and their normals (N, 3).

    ``given`` (3,) is used as it is (the room's horizontal axes are still estimated and made perpendicular
    to it). Otherwise the cloud is asked: each signed axis of its Manhattan frame is scored by its floor
    (:func:`floor_scores`); the best wins unless the axis nearest ``hint`` (3,) scores at least 1 /
    :data:`HINT_TIE` of it and is sure of it (a near tie, or a cloud torn between two other axes: the hint,
    the input's convention or its cameras' up, decides); a convention the cloud did not overrule still
    gives way to an axis across it whose floor is open above (:data:`OPEN_FLOOR`). Unless ``hint`` is the
    mean up of the cameras that saw the points (``cameras``), a depth image in a camera's frame
    (:func:`is_camera_view`) takes the axis nearest that camera's up, -y, as a frame does (a camera is
    rarely upside down or rolled past 45 degrees): one view of a wall with a ceiling strip reads as well on
    its side or upside down; but the file's own up (``hint``) wins when it scores a floor of at least
    :data:`OWN_FLOOR` and more than the camera's -y (a room scan stored above z = 0.1 m can pass for a
    camera's view from below it). The chosen axis settles on its surfaces (:func:`settle_axis`) and becomes
    its floor's normal (:func:`floor_normal`); the horizontal axes are made perpendicular to it. Without a
    Manhattan frame, or when the chosen axis carries under ``min_support`` of the normals and lies more
    than 45 degrees from the hint, the hint is used as it is.
    A confidence under :data:`UNSURE` comes with a warning, unless the axis the cloud scores best is the
    one nearest the hint and not in a tie (:data:`TIE`)."""
    hint = np.asarray(hint, dtype=np.float64)
    hint = hint / np.linalg.norm(hint)
    source, own = "estimated", hint
    if not cameras and is_camera_view(points):
        hint, source = np.array([0.0, -1.0, 0.0]), "camera"
    ok = np.linalg.norm(normals, axis=1) > 0.5
    try:
        frame, support = manhattan_frame(normals[ok], np.random.default_rng(seed))
    except ValueError:
        frame, support = None, np.zeros(3)
    if given is not None:
        up = np.asarray(given, dtype=np.float64)
        up = up / np.linalg.norm(up)
        if frame is not None:
            frame = refine_frame(points[ok], normals[ok], frame)
        axes = manhattan_axes(-up, _reorder(frame, up)) if frame is not None else None
        return RoomUp(up, axes, "given", _support(support, frame, up))
    if frame is None:
        why = "no two perpendicular surfaces in the cloud"
        return RoomUp(hint, None, "camera" if source == "camera" else "hint", confidence=0.0,
                      warning=_unsure(hint, why))  # fmt: skip
    scores = floor_scores(points[ok], normals[ok], frame)
    signed = np.stack([frame, -frame], axis=2).reshape(3, 6)  # columns +a0, -a0, +a1, ...
    mine, cams = scores[int((signed.T @ own).argmax())], scores[int((signed.T @ hint).argmax())]
    if source == "camera" and mine >= OWN_FLOOR and mine > cams:  # a room scan stored above z = 0.1 m
        hint, source = own, "estimated"
    near = int((signed.T @ hint).argmax())
    best = int(scores.argmax())
    # a camera is rarely upside down or rolled past 45 degrees (as for a frame): its up is not overruled
    sure = scores[best] > 0 and 1.0 - np.delete(scores, best).max() / scores[best] >= UNSURE
    overrule = source != "camera" and scores[best] > HINT_TIE * scores[near] and sure
    pick = best if overrule else near
    if not (overrule or cameras or source == "camera"):
        pick = _open_floor(scores, near)
    confidence = _confidence(scores, pick)
    up = settle_axis(normals[ok], signed[:, pick])
    up = floor_normal(points[ok], normals[ok], up)
    if support[pick // 2] < min_support and float(up @ hint) < np.cos(np.deg2rad(45.0)):
        axes = manhattan_axes(-hint, _reorder(frame, hint))
        why = "the cloud's up axis carries few surfaces"
        return RoomUp(hint, axes, "hint", _support(support, frame, hint), 0.0, _unsure(hint, why))
    # the walls' axes refined on their own planes, then made perpendicular to up
    axes = manhattan_axes(-up, _reorder(refine_frame(points[ok], normals[ok], frame), up))
    warning = ""
    # a low margin that the input's own up (its convention, its cameras) agrees with is no doubt worth a
    # warning (a floor and four walls without a ceiling: 0.13), unless it is a tie
    if confidence < UNSURE and (best != near or confidence < TIE):
        warning = _unsure(up, "its floor is not clearly the lowest large plane of one direction")
    return RoomUp(up, axes, source, _support(support, frame, up), confidence, warning)


def _confidence(scores: np.ndarray, pick: int) -> float:
    """How clearly the cloud names the signed axis ``pick`` up: 1 less the ratio of the next axis's value to
    its own, by floor score or, when its floor is open above (:data:`OPEN_FLOOR`), by that margin (each
    score less its opposite's), whichever is clearer. A long room with low walls scores a wall about as well
    as its floor (0.092 against 0.080 in a real scan), but the wall faces the opposite wall (0.037) and the
    floor no ceiling."""
    margin = scores - scores[np.arange(6) ^ 1]
    out = 0.0
    for values, least in ((scores, 0.0), (margin, OPEN_FLOOR)):
        rest = np.delete(values, pick)
        if values[pick] > 0 and values[pick] >= least:
            out = max(out, float(np.clip(1.0 - rest.max() / values[pick], 0.0, 1.0)))
    return out


def _open_floor(scores: np.ndarray, near: int) -> int:
    """The signed axis (index into ``scores``, :func:`floor_scores`' order) across the axis ``near`` of the
    input's convention whose floor is open above and beats it (:data:`OPEN_FLOOR`), else ``near``. A
    convention with no floor at all may also give way to its own axis reversed: a scan stored upside down
    whose ceiling was not scanned (a ceiling scanned whole over a floor that furniture hides would read as
    a floor open above, so a convention that has a floor is never reversed)."""
    margin = scores - scores[np.arange(6) ^ 1]  # each axis's score less its opposite's
    across = [
        k
        for k in range(6)
        if (k // 2 != near // 2 or scores[near] <= 0)
        and margin[k] >= OPEN_FLOOR
        and margin[k] > margin[near]
        and scores[k] >= OPEN_SHARE * scores[near]
    ]
    return max(across, key=lambda k: margin[k]) if across else near


def _unsure(up: np.ndarray, why: str) -> str:
    text = ",".join(f"{v:.2g}" for v in up)
    return f"up direction unsure ({why}); fitted with up {text}, pass --up to set it"


def _reorder(frame: np.ndarray, up: np.ndarray) -> np.ndarray:
    """The frame's columns with the one nearest ``up`` first (what :func:`manhattan_axes` expects)."""
    k = int(np.abs(frame.T @ up).argmax())
    others = [a for a in range(3) if a != k]
    return frame[:, [k, *others]]


def _support(support: np.ndarray, frame: np.ndarray | None, up: np.ndarray) -> tuple[float, float, float]:
    if frame is None:
        return (0.0, 0.0, 0.0)
    k = int(np.abs(frame.T @ up).argmax())
    others = [a for a in range(3) if a != k]
    return (float(support[k]), float(support[others[0]]), float(support[others[1]]))

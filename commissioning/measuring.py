"""Measuring a landmark by switching its LED against the lit ceiling (docs/commissioning.md).

A localized robot's frames are placed on the ceiling (each spot's ray from the camera, at
the robot's estimate for that very frame, meets the plane of the LED's height), so a spot
that hangs still stays in one place whether the robot moves or not. A frame with the target
LED lit and one with it dark, the other LEDs the same, differ by the target's spot: a
*candidate* (`lone_spots`). A candidate is the target only when it switched in step with it
over several of its cycles (`switch_record`): in every kept frame that would have seen its
place, present while the target was lit and absent while it was dark, through at least
`min_cycles` lit phases and the dark ones between. A spot that merely flickers (a faint
glint, a landmark at the edge of detection, a person passing) breaks that and is never
measured. The accepted spot of each lit frame is one *sample*; the median of agreeing
samples is the measurement. Pure: numpy in, values out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from commissioning.doubt import expected_in_view
from commissioning.geometry import point_in_view_from_poses, points_on_ceiling
from commissioning.types import MapLandmark
from localizer.camera import CameraModel
from localizer.geometry import T_world_body_from_pose
from localizer.types import FloatArray


@dataclass(frozen=True, eq=False)
class PlacedFrame:
    """One frame's spots on the ceiling.

    Attributes:
        t_ns: the frame's time.
        lit: the other landmarks lit at the frame (confirmed, settled; the target excluded).
        target_on: whether the target LED was lit.
        pixels: spot centroids (col, row), shape (N, 2).
        points: the spots on the ceiling plane, world frame, metres, shape (N, 3) (NaN rows:
            rays that miss it).
        pose: the robot's (x, y, theta) for the frame.
        changing: other landmarks whose LED may have been either way at the frame (being
            switched, or switched too recently), their last confirmed state in `lit`.
    """

    t_ns: int
    lit: frozenset[int]
    target_on: bool
    pixels: FloatArray
    points: FloatArray
    pose: tuple[float, float, float]
    changing: frozenset[int] = frozenset()


def place_spots(
    camera: CameraModel,
    pose: tuple[float, float, float],
    pixels: npt.ArrayLike,
    height: float,
) -> FloatArray:
    """Spots (N, 2) of a robot at (x, y, theta) on the plane z = `height`, shape (N, 3)."""
    px = np.asarray(pixels, dtype=np.float64).reshape(-1, 2)
    return points_on_ceiling(camera, T_world_body_from_pose(*pose), px, height)


def lone_spots(
    camera: CameraModel, on: PlacedFrame, off: PlacedFrame, *, match_m: float, margin_px: float
) -> FloatArray:
    """The spots of the lit frame with no spot of the dark frame within `match_m`
    (horizontally) that the dark frame would have seen (inside its image by `margin_px`: a
    spot that left the view as the robot moved is no switch), shape (K, 3)."""
    p_on = on.points[np.all(np.isfinite(on.points), axis=1)]
    p_off = off.points[np.all(np.isfinite(off.points), axis=1)]
    if len(p_on) == 0:
        return p_on
    if len(p_off):
        d = np.linalg.norm(p_on[:, None, :2] - p_off[None, :, :2], axis=2)
        p_on = p_on[d.min(axis=1) > match_m]
    seen = expected_in_view(camera, off.pose, p_on, margin_px=margin_px)
    return np.asarray(p_on[seen], dtype=np.float64)


@dataclass(frozen=True)
class SwitchRecord:
    """How one place on the ceiling behaved over the kept frames.

    Attributes:
        lit_phases: lit phases of the target (runs of frames with it lit) in which the place
            was in view.
        dark_phases: dark phases in which it was in view.
        misses: frames with the target lit that would have seen the place and show no spot
            there.
        extras: frames with the target dark that would have seen the place and show a spot
            there.
        in_step: other landmarks whose LEDs may have been lit in exactly those frames with
            the target lit (a robot's identification probe in step with the wizard): the
            spot could be theirs.
    """

    lit_phases: int
    dark_phases: int
    misses: int
    extras: int
    in_step: frozenset[int] = frozenset()

    @property
    def broken(self) -> bool:
        """It did not follow the target's LED: missing once while lit, or shown once dark."""
        return self.misses > 0 or self.extras > 0

    def switched(self, min_cycles: int) -> bool:
        """It followed the target through `min_cycles` lit phases and the dark ones between."""
        return (
            not self.broken
            and not self.in_step
            and self.lit_phases >= min_cycles
            and self.dark_phases >= min_cycles - 1
        )


def switch_record(
    camera: CameraModel,
    point: npt.ArrayLike,
    frames: Sequence[PlacedFrame],
    *,
    match_m: float,
    margin_px: float,
) -> SwitchRecord:
    """How the place `point` (3,) (world, metres) followed the target's LED over `frames`
    (in time order): each frame that would have seen it (inside its image by `margin_px`,
    from the frame's own pose, so the robot may move) should show a spot within `match_m`
    of it (horizontally, on the ceiling) exactly when the target was lit; and no other
    landmark's LED may have switched with the target in those frames."""
    p = np.asarray(point, dtype=np.float64).reshape(3)
    if not frames:
        return SwitchRecord(0, 0, 0, 0)
    on = np.array([f.target_on for f in frames], dtype=bool)
    run = np.concatenate([[0], np.cumsum(on[1:] != on[:-1])])  # the target's phases
    poses = np.array([f.pose for f in frames], dtype=np.float64)
    seen = point_in_view_from_poses(camera, poses, p, margin_px=margin_px)
    counts = [len(f.points) for f in frames]
    pts = np.concatenate([f.points for f in frames]).reshape(-1, 3)
    d = np.linalg.norm(np.nan_to_num(pts[:, :2], nan=np.inf) - p[:2], axis=1)
    near = np.zeros(len(frames), dtype=bool)
    near[np.repeat(np.arange(len(frames)), counts)[d <= match_m]] = True
    lit, dark = seen & on, seen & ~on
    maybe_lit: frozenset[int] | None = None  # other LEDs perhaps lit in every lit frame
    surely_lit_dark: set[int] = set()  # ... less those surely lit in some dark frame
    for k in np.flatnonzero(seen).tolist():
        f = frames[k]
        if f.target_on:
            here = f.lit | f.changing
            maybe_lit = here if maybe_lit is None else maybe_lit & here
        else:
            surely_lit_dark |= f.lit - f.changing
    in_step = frozenset() if maybe_lit is None or not dark.any() else maybe_lit - surely_lit_dark
    return SwitchRecord(
        lit_phases=len(set(run[lit].tolist())),
        dark_phases=len(set(run[dark].tolist())),
        misses=int(np.sum(lit & ~near)),
        extras=int(np.sum(dark & near)),
        in_step=frozenset(in_step),
    )


@dataclass(frozen=True, eq=False)
class SwitchedSpot:
    """What the newest lit frame tells of the target's spot.

    Attributes:
        point: the target's spot in that frame on the ceiling (world, metres, shape (3,));
            None when no candidate switched in step with it, or more than one did.
        pixel: that spot's centroid (col, row) in the frame; None with `point`.
        candidates: spots of the frame missing from the latest dark frame (`lone_spots`).
        switched: how many of them followed the target through `min_cycles` (more than one:
            reflections, no sample).
        flickering: candidates that did not follow it (shown while it was dark, or missing
            while it was lit), (x, y) on the ceiling, metres.
    """

    point: FloatArray | None
    pixel: tuple[float, float] | None
    candidates: int
    switched: int
    flickering: tuple[tuple[float, float], ...]


def switched_spot(
    camera: CameraModel,
    frames: Sequence[PlacedFrame],
    *,
    match_m: float,
    margin_px: float,
    min_cycles: int,
) -> SwitchedSpot | None:
    """The target's spot in the newest frame of `frames` (time order), when that frame has
    the target lit and a dark frame precedes it; else None.

    The candidates are the newest frame's spots that the latest dark frame lacks
    (`lone_spots`: a landmark a robot darkened meanwhile is one too); each must then follow
    the target's LED over all `frames` (`switch_record`), which such a landmark does not.
    Exactly one that does is the sample."""
    if not frames or not frames[-1].target_on:
        return None
    on = frames[-1]
    off = next((f for f in reversed(frames) if not f.target_on), None)
    if off is None:
        return None
    lone = lone_spots(camera, on, off, match_m=match_m, margin_px=margin_px)
    good: list[FloatArray] = []
    flickering: list[tuple[float, float]] = []
    for p in lone:
        record = switch_record(camera, p, frames, match_m=match_m, margin_px=margin_px)
        if record.switched(min_cycles):
            good.append(p)
        elif record.broken:
            flickering.append((float(p[0]), float(p[1])))
    if len(good) != 1:
        return SwitchedSpot(None, None, len(lone), len(good), tuple(flickering))
    point = np.asarray(good[0], dtype=np.float64)
    rows = np.linalg.norm(np.nan_to_num(on.points, nan=1e9) - point, axis=1)
    k = int(np.argmin(rows))
    pixel = (float(on.pixels[k, 0]), float(on.pixels[k, 1]))
    return SwitchedSpot(point, pixel, len(lone), 1, tuple(flickering))


@dataclass(frozen=True)
class Agreement:
    """Samples that agree.

    Attributes:
        position: their median, world frame, metres, shape (3,).
        count: how many agree (within `agree_m` of the median, horizontally).
        spread_m: the largest horizontal distance of one of them from the median, metres.
    """

    position: tuple[float, float, float]
    count: int
    spread_m: float


def agreement(samples: Sequence[FloatArray], *, agree_m: float, needed: int) -> Agreement | None:
    """The last `needed` samples, when all lie within `agree_m` of their median; else None."""
    if len(samples) < needed:
        return None
    last = np.array(samples[-needed:], dtype=np.float64).reshape(-1, 3)
    med = np.median(last, axis=0)
    spread = float(np.max(np.linalg.norm(last[:, :2] - med[:2], axis=1)))
    if spread > agree_m:
        return None
    return Agreement((float(med[0]), float(med[1]), float(med[2])), needed, spread)


@dataclass(frozen=True)
class Plausibility:
    """A measured position against the map.

    Attributes:
        distance_m: horizontal distance from the map's position, metres (None: a new radio).
        far: farther than the limit from where the map puts it (or outside the mapped area
            for a new radio): confirming it needs an explicit "yes, it moved".
        note: for people.
    """

    distance_m: float | None
    far: bool
    note: str


def plausibility(
    position: Sequence[float],
    known: MapLandmark | None,
    others: Sequence[MapLandmark],
    *,
    far_m: float,
) -> Plausibility:
    """Whether a measured position is where the map roughly expects it."""
    x, y = float(position[0]), float(position[1])
    if known is not None:
        d = math.hypot(x - known.x, y - known.y)
        if d > far_m:
            note = (
                f"{d:.2f} m from its map position ({known.x:.2f}, {known.y:.2f}): far; "
                "confirm only if the landmark was really moved there"
            )
            return Plausibility(d, True, note)
        return Plausibility(d, False, f"{100 * d:.1f} cm from its map position")
    if not others:
        return Plausibility(None, False, "new landmark")
    xs = [lm.x for lm in others]
    ys = [lm.y for lm in others]
    outside = max(min(xs) - x, x - max(xs), min(ys) - y, y - max(ys), 0.0)
    if outside > far_m:
        note = f"{outside:.2f} m outside the mapped area: confirm only if the radio hangs there"
        return Plausibility(None, True, note)
    return Plausibility(None, False, "new landmark, inside the mapped area")

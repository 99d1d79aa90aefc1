"""Measuring a landmark by switching its LED against the lit ceiling (docs/commissioning.md).

A localized robot's frames are placed on the ceiling (each spot's ray from the camera, at
the robot's estimate for that very frame, meets the plane of the LED's height). A frame
with the target LED lit and one with it dark, the other LEDs the same, differ by one spot:
the target's. Its world position is one *sample*; samples from successive pairs agree when
the robot is well localized, whether it moves or not, and the median of agreeing samples is
the measurement. Pure: numpy in, values out.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
import numpy.typing as npt

from commissioning.doubt import expected_in_view
from commissioning.geometry import points_on_ceiling
from commissioning.types import MapLandmark
from localizer.camera import CameraModel
from localizer.geometry import T_world_body_from_pose

FloatArray = npt.NDArray[np.float64]


@dataclass(frozen=True, eq=False)
class PlacedFrame:
    """One frame's spots on the ceiling.

    Attributes:
        t_ns: the frame's time.
        lit: the landmarks lit at the frame (confirmed, settled).
        target_on: whether the target LED was lit.
        pixels: spot centroids (col, row), shape (N, 2).
        points: the spots on the ceiling plane, world frame, metres, shape (N, 3) (NaN rows:
            rays that miss it).
        pose: the robot's (x, y, theta) for the frame.
    """

    t_ns: int
    lit: frozenset[int]
    target_on: bool
    pixels: FloatArray
    points: FloatArray
    pose: tuple[float, float, float]


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


def switched_spot(
    camera: CameraModel, on: PlacedFrame, off: PlacedFrame, *, match_m: float, margin_px: float
) -> FloatArray | None:
    """The one spot that switched between the frames (`lone_spots`), shape (3,); None when
    there is none or more than one."""
    lone = lone_spots(camera, on, off, match_m=match_m, margin_px=margin_px)
    return np.asarray(lone[0], dtype=np.float64) if len(lone) == 1 else None


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

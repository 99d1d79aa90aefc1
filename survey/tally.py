"""What a landmark's spots showed over a drive (`Tally`: views, residuals, sightings set
aside, conflicts), gathered window by window so that an incremental survey reports the whole
drive's evidence without keeping its spots (`survey.incremental`)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from localizer.types import FloatArray, IntArray
from survey.layout import Fit
from survey.observations import LabelledObservations


@dataclass(frozen=True)
class Tally:
    """One landmark's evidence.

    Attributes:
        observations: spots used; views: independent views (robot positions at least
            `spacing_m` apart, in time order); last_view: the last one counted (x, y).
        sq_err, n_err, max_err: its spots' reprojection errors (sum of squares, count,
            largest), pixels.
        sightings: spots named it (used or not); set_aside: of them, in tracks set aside.
        conflicts: frames in which two spots were named it.
    """

    observations: int = 0
    views: int = 0
    last_view: tuple[float, float] | None = None
    first_view: tuple[float, float] | None = None
    sq_err: float = 0.0
    n_err: int = 0
    max_err: float = 0.0
    sightings: int = 0
    set_aside: int = 0
    conflicts: int = 0

    @property
    def rms_px(self) -> float:
        return math.sqrt(self.sq_err / self.n_err) if self.n_err else float("nan")

    @property
    def max_px(self) -> float:
        return self.max_err if self.n_err else float("nan")

    def plus(self, other: Tally, spacing_m: float) -> Tally:
        """This tally followed by `other` (a later stretch of the drive, counted from no
        view: its first view counts only if far enough from this one's last)."""
        views = self.views + other.views
        if self.last_view is not None and other.first_view is not None:
            near = math.dist(self.last_view, other.first_view) < spacing_m
            views -= int(near)
        return Tally(
            self.observations + other.observations,
            views,
            other.last_view if other.last_view is not None else self.last_view,
            self.first_view if self.first_view is not None else other.first_view,
            self.sq_err + other.sq_err,
            self.n_err + other.n_err,
            max(self.max_err, other.max_err),
            self.sightings + other.sightings,
            self.set_aside + other.set_aside,
            max(self.conflicts, other.conflicts),
        )


def count_views(positions: FloatArray, spacing_m: float) -> tuple[int, FloatArray | None]:
    """Views (robot positions in time order) at least `spacing_m` from the last counted one,
    and the last counted."""
    count, last = 0, None
    for p in positions:
        if last is None or float(np.hypot(*(p - last))) >= spacing_m:
            count += 1
            last = p
    return count, last


def tallies(
    obs: LabelledObservations,
    fit: Fit,
    labels: IntArray,
    rejected: set[int],
    spacing_m: float,
    *,
    keys_before: int | None = None,
    frames_before: int | None = None,
) -> dict[int, Tally]:
    """Each landmark's tally over `fit`'s observations (those of keyframes before
    `keys_before`, and sightings in frames before `frames_before`, when given)."""
    poses = fit.poses()
    out: dict[int, Tally] = {}
    in_frames = np.ones(len(obs.frame), dtype=bool)
    if frames_before is not None:
        in_frames = obs.frame < frames_before
    set_aside_rows = np.isin(obs.track, np.fromiter(rejected, dtype=np.int64))
    for lid in sorted(set(fit.lay.free_ids) | {int(i) for i in fit.o_id.tolist()}):
        sel = fit.o_id == lid
        if keys_before is not None:
            sel &= fit.o_key < keys_before
        rows = np.flatnonzero(sel)
        e = fit.err[rows][fit.valid[rows]]
        xy = poses[fit.o_key[rows], :2]
        views, last = count_views(xy, spacing_m)
        all_rows = ((obs.landmark_id == lid) | (labels == lid)) & in_frames
        out[lid] = Tally(
            len(rows),
            views,
            None if last is None else (float(last[0]), float(last[1])),
            None if len(xy) == 0 else (float(xy[0, 0]), float(xy[0, 1])),
            float(np.sum(e**2)),
            len(e),
            float(np.max(e)) if len(e) else 0.0,
            int(np.sum(all_rows)),
            int(np.sum(all_rows & set_aside_rows)),
            int(obs.conflicts.get(lid, 0)),
        )
    return out

"""The live survey's running estimate: the incremental survey (`survey.incremental`) updated
from the drive every few seconds in the solver's worker, and kept in a file of the data
directory after each update (`survey.incremental_file`), so that a restart of the server
loses none of it; and the route it suggests over what is still uncertain."""

from __future__ import annotations

import contextlib
import logging
import math
from collections.abc import Iterable
from pathlib import Path

import numpy as np

from live.survey.live import LiveDrive, LiveSurveyConfig
from live.survey.solver import SurveySolver
from survey.incremental import IncrementalSurvey
from survey.incremental_file import load, save
from survey.result import SurveyResult
from survey.route import suggest_route

log = logging.getLogger(__name__)

STATE_FILE = "survey-estimate.npz"
"""The running estimate's file in the data directory."""


class RunningEstimate:
    """One survey's running estimate (used by one thread at a time: the survey's estimate
    loop, or the service while it starts or ends a drive)."""

    def __init__(self, data_dir: Path | None, solver: SurveySolver, config: LiveSurveyConfig):
        self.path = None if data_dir is None else Path(data_dir) / STATE_FILE
        self.solver, self.config = solver, config
        self.state = IncrementalSurvey()

    def saved(self) -> tuple[IncrementalSurvey, dict[str, object]] | None:
        """The estimate a previous run of the server left, with what it needs to resume
        (None: none, or a file that is not one: logged and left for staff to look at)."""
        if self.path is None or not self.path.exists():
            return None
        try:
            return load(self.path)
        except ValueError as exc:
            log.warning("survey: the saved estimate is not used: %s", exc)
            return None

    def begin(self, resume: IncrementalSurvey | None) -> None:
        """Start a drive: from nothing, or going on from `resume` (the robot's wheels have
        a gap since, so its last pose is not carried: `IncrementalSurvey.restarted`)."""
        self.state = IncrementalSurvey() if resume is None else resume.restarted()

    def step(
        self, drive: LiveDrive, anchors: Iterable[int], extra: dict[str, object]
    ) -> SurveyResult | None:
        """Update from what the drive brought since the last update and save; None when there
        is not enough to solve yet. Raises ValueError (an anchor not identified yet) or
        `SolveCancelledError` as the solver does."""
        window = drive.snapshot(self.state.window_start_ns)
        if len(window.frame_t_ns) < 2 or len(window.odom_t_ns) == 0:
            return None
        cfg = self.config
        self.state = self.solver.update(self.state, window, anchors, cfg.bundle, cfg.incremental)
        start = self.state.window_start_ns
        if start is not None and start >= 0:
            drive.forget_before(start)
        self.save(extra)
        return self.state.result

    def save(self, extra: dict[str, object]) -> None:
        if self.path is None:
            return
        try:
            save(self.state, self.path, extra)
        except OSError as exc:  # a full disk must not end the drive
            log.warning("survey: the running estimate was not saved: %s", exc)

    def discard(self) -> None:
        """Forget the estimate and its file (the survey was cancelled, or solved)."""
        self.state = IncrementalSurvey()
        if self.path is not None:
            with contextlib.suppress(FileNotFoundError):
                self.path.unlink()


def route_over(
    result: SurveyResult,
    robot_xy: tuple[float, float],
    map_xy: dict[int, tuple[float, float]],
    config: LiveSurveyConfig,
) -> tuple[tuple[float, float], ...]:
    """Waypoints from the robot over what `result` leaves uncertain (`survey.route`):
    every landmark of the map at its estimate (or map position when not placed)."""
    if not map_xy:
        return ()
    xy, sig = [], []
    for lid, at in map_xy.items():
        e = result.landmarks.get(lid)
        xy.append(at if e is None else (float(e.position[0]), float(e.position[1])))
        sig.append(math.nan if e is None else (0.0 if e.anchor else e.sigma_m))
    pos = np.array(xy)
    m = config.site_margin_m
    lo, hi = pos.min(axis=0) - m, pos.max(axis=0) + m
    route = suggest_route(
        robot_xy,
        pos,
        sig,
        (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])),
        visited_xy=result.trajectory[:, :2],
        config=config.route,
    )
    return tuple((float(x), float(y)) for x, y in route)

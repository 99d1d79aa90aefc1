"""The survey's solves in a process of their own.

A bundle adjustment is seconds of Python (finite differences, the windows' bookkeeping). In a
thread of the server it holds the interpreter lock that the site's robots, the radio and the
survey's own blinks need: on a 2-core machine a live survey's blink windows stretched from
0.14 s to 0.34 s and its camera fell from 29 to 21 frames a second while the live estimate
solved, so the drive took three times as long. In a worker process the solve takes a core
of its own and nothing of the server's lock.

The worker is started (spawned, not forked: the server has threads) on the first solve and
killed when a solve is no longer wanted (`cancel`), so that a drive's end or the server's
shutdown never waits for a solve to finish.
"""

from __future__ import annotations

import dataclasses
import multiprocessing
import multiprocessing.pool
import threading
from collections.abc import Callable, Iterable
from pathlib import Path

from survey.bundle import BundleConfig, solve_survey
from survey.drive import SurveyDrive, read_survey_drive, survey_problem
from survey.incremental import IncrementalConfig, IncrementalSurvey
from survey.incremental import update as incremental_update
from survey.result import SurveyResult

_POLL_S = 0.1


class SolveCancelledError(Exception):
    """The solve was cancelled (`SurveySolver.cancel`) before it finished."""


def solve_drive(drive: SurveyDrive, anchors: list[int], config: BundleConfig) -> SurveyResult:
    """Name the drive's spots and solve it (in the worker)."""
    return solve_survey(survey_problem(drive, anchors), config)


def solve_recording(
    path: Path, anchors: list[int], config: BundleConfig, leave_out: tuple[int, ...] = ()
) -> SurveyResult:
    """Read a survey recording and solve it (in the worker), without the landmarks
    `leave_out` (those the radio cannot switch: the LED states never list them lit)."""
    drive = read_survey_drive(path)
    if leave_out:
        kept = [lm for lm in drive.landmarks if lm.id not in set(leave_out)]
        drive = dataclasses.replace(drive, landmarks=kept)
    return solve_drive(drive, anchors, config)


def _ready() -> None:
    """Nothing: unpickling it in the worker imports this module and the solver."""


class SurveySolver:
    """One worker process for the survey's solves, one solve at a time (thread-safe)."""

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pool: multiprocessing.pool.Pool | None = None
        self._generation = 0  # counts cancels: a solve begun before one is cancelled

    def drive(
        self, drive: SurveyDrive, anchors: Iterable[int], config: BundleConfig
    ) -> SurveyResult:
        """`solve_drive` in the worker. Raises what the solve raises (ValueError: the drive
        cannot be solved yet), or SolveCancelledError."""
        return _result(self._run(solve_drive, drive, list(anchors), config))

    def update(
        self,
        state: IncrementalSurvey,
        window: SurveyDrive,
        anchors: Iterable[int],
        config: BundleConfig,
        inc: IncrementalConfig,
    ) -> IncrementalSurvey:
        """`survey.incremental.update` in the worker (the live estimate); raises as `drive`."""
        out = self._run(incremental_update, state, window, list(anchors), config, inc)
        if not isinstance(out, IncrementalSurvey):
            raise TypeError(f"survey worker returned {type(out).__name__}")
        return out

    def recording(
        self,
        path: Path,
        anchors: Iterable[int],
        config: BundleConfig,
        *,
        leave_out: tuple[int, ...] = (),
    ) -> SurveyResult:
        """`solve_recording` in the worker; raises as `drive` does."""
        return _result(self._run(solve_recording, path, list(anchors), config, leave_out))

    def start(self) -> None:
        """Start the worker ahead of the first solve (it takes seconds to import what the
        solve needs); returns at once."""
        with self._lock:
            self._ensure().apply_async(_ready)

    def cancel(self) -> None:
        """Kill the worker and whatever it solves (a new one starts with the next solve)."""
        with self._lock:
            pool, self._pool = self._pool, None
            self._generation += 1
        if pool is not None:
            pool.terminate()
            pool.join()

    close = cancel

    def _ensure(self) -> multiprocessing.pool.Pool:
        if self._pool is None:
            self._pool = multiprocessing.get_context("spawn").Pool(1)
        return self._pool

    def _run(self, fn: Callable[..., object], *args: object) -> object:
        with self._lock:
            pending, generation = self._ensure().apply_async(fn, args), self._generation
        while True:  # the worker's exceptions are raised here; a killed worker answers never
            try:
                result = pending.get(timeout=_POLL_S)
            except multiprocessing.TimeoutError:
                if self._generation != generation:
                    raise SolveCancelledError from None
                continue
            return result


def _result(out: object) -> SurveyResult:
    if not isinstance(out, SurveyResult):
        raise TypeError(f"survey worker returned {type(out).__name__}")
    return out

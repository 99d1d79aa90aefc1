"""The live survey: one robot drives while the landmarks it sees blink, the estimate of every
landmark is updated on the way, then `survey.solve_survey` places them all (docs/survey.md).

An admin starts it with a robot (`start`): the robot's frames, odometry and LED states are
recorded (`Recordings`) and kept in memory (`live.survey.live.LiveDrive`). A blink driver
asks the LED coordinator, as the requester "survey", to darken one landmark at a time against
the lit ceiling (`survey.blinks.BlinkConfig` timing), as robots identify themselves: of the
landmarks the surveying robot expects in view, those not yet identified or not yet
converged, never one another robot uses or expects (`live.survey.live.blink_choice`). Every
few seconds the drive so far is solved again (the live estimate, with each landmark's state,
and a suggested route over what is still uncertain: `survey.route`). `stop` ends the drive
and solves on the recording; both solves run in a worker process (`live.survey.solver`).
The locked landmarks are the anchors, every other landmark's map position is its rough
position. Results are proposals: `accept` writes
the chosen landmarks' positions through the map's data layer (audited, undoable), never
silently; `cancel` drops the survey.
"""

from __future__ import annotations

import contextlib
import logging
import math
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Literal

import numpy as np

from live.survey.blinks import BlinkDriver
from live.survey.live import (
    LandmarkSurveyState,
    LiveDrive,
    LiveSurveyConfig,
    landmark_state,
)
from live.survey.solver import SolveCancelledError, SurveySolver
from localizer.events import Event
from store.errors import ConflictError, NotFoundError, UnavailableError
from store.models import LandmarkUpdate
from survey.blinks import BlinkConfig
from survey.bundle import BundleConfig
from survey.result import LandmarkEstimate, SurveyResult
from survey.route import suggest_route
from survey.survey_map import SurveyLandmark

if TYPE_CHECKING:  # the facades are handed in (live.services); typing only
    from live.facades import LedsAndRadio, Recordings, Robots
    from store.landmarks import MapRepository

log = logging.getLogger(__name__)

State = Literal["idle", "driving", "solving", "done", "failed"]


@dataclass(frozen=True)
class Proposal:
    """One landmark's surveyed position (metres, world frame) against the map's.

    `ellipse`: the horizontal 1-sigma ellipse (major m, minor m, angle of the major axis rad);
    `state`: anchor, converging, converged or flagged (`live.survey.live.landmark_state`).
    """

    landmark_id: int
    x: float
    y: float
    z: float
    sigma_m: float
    moved_m: float
    views: int
    rms_px: float
    anchor: bool
    flags: tuple[str, ...]
    ellipse: tuple[float, float, float] = (0.0, 0.0, 0.0)
    state: LandmarkSurveyState = "converging"


@dataclass(frozen=True)
class SurveyStatus:
    """Where the survey is.

    Attributes:
        state: idle, driving (recording, blinking, estimating), solving, done (the final
            proposals) or failed (`message` says why).
        robot: the surveying robot; recording: its recording folder.
        started_s: seconds since the drive started (None when idle).
        blinks: dark windows requested so far.
        proposals: the estimate, landmark by landmark: the live one while driving (and
            solving), the final one when done.
        accepted: landmarks whose proposal was written into the map.
        unseen: landmarks of the map the estimate could not place (yet).
        drive_s: robot time the estimate covers, seconds (0 before the first estimate).
        estimates: live estimates made so far.
        route: suggested waypoints ((x, y) metres) over what is still uncertain.
        converged_sigma_m: the 1-sigma at or under which a landmark counts as converged.
        no_radio: landmarks of the map left out of the survey because the radio cannot
            switch them (no radio address): they cannot blink, so nothing names them, and
            counted as dark they would make every blink ambiguous.
    """

    state: State
    robot: str | None = None
    recording: str | None = None
    started_s: float | None = None
    blinks: int = 0
    message: str = ""
    proposals: tuple[Proposal, ...] = ()
    accepted: tuple[int, ...] = ()
    unseen: tuple[int, ...] = field(default=())
    drive_s: float = 0.0
    estimates: int = 0
    route: tuple[tuple[float, float], ...] = ()
    converged_sigma_m: float = 0.005
    no_radio: tuple[int, ...] = ()


class LiveSurvey:
    """Drive a survey with one robot (thread-safe; blinking and the live estimate run in
    threads of their own)."""

    def __init__(
        self,
        map: MapRepository,
        robots: Robots,
        leds: LedsAndRadio,
        recordings: Recordings,
        *,
        blinks: BlinkConfig | None = None,
        bundle: BundleConfig | None = None,
        live: LiveSurveyConfig | None = None,
    ) -> None:
        self.map, self.robots, self.leds, self.recordings = map, robots, leds, recordings
        self.blinks = blinks or BlinkConfig()
        self.bundle = bundle or BundleConfig()
        self.live = live or LiveSurveyConfig()
        self._lock = threading.Lock()
        self._state: State = "idle"
        self._robot: str | None = None
        self._recording: Path | None = None
        self._t0 = 0.0
        self._count = 0
        self._message = ""
        self._result: SurveyResult | None = None
        self._drive_s = 0.0
        self._estimates = 0
        self._route: tuple[tuple[float, float], ...] = ()
        self._accepted: list[int] = []
        self._no_radio: tuple[int, ...] = ()
        self._stop = threading.Event()
        self._threads: list[threading.Thread] = []
        self._drive: LiveDrive | None = None
        self._tap: tuple[str, Callable[[Event], None]] | None = None
        self._solver = SurveySolver()  # the solves, in a process of their own

    def anchors(self) -> list[int]:
        """The locked landmarks: they keep their surveyed positions and fix the map's frame."""
        return [lm.id for lm in self.map.list() if lm.locked]

    def start(self, robot: str, *, actor: str) -> SurveyStatus:
        """Start recording `robot`, blinking and estimating. ConflictError while a survey
        drives or solves, or with fewer than two locked landmarks; UnavailableError without
        a radio; NotFoundError for an unknown robot; ValueError for a robot that cannot be
        recorded here.

        Landmarks the radio cannot switch (no radio address) are left out and reported
        (`SurveyStatus.no_radio`); an anchor without one is refused (ConflictError)."""
        if self.leds.coordinator is None:
            raise UnavailableError("no radio: the site runs without a gateway, nothing can blink")
        names = self.robots.names()
        if robot not in names:
            raise NotFoundError(f"unknown robot {robot!r}; robots: {', '.join(sorted(names))}")
        every = self.map.list()
        switchable = self.leds.controlled
        lms = [lm for lm in every if lm.id in switchable]
        no_radio = tuple(sorted(lm.id for lm in every if lm.id not in switchable))
        dumb_anchors = [lm.id for lm in every if lm.locked and lm.id not in switchable]
        if dumb_anchors:
            raise ConflictError(
                f"anchor landmark(s) {', '.join(map(str, dumb_anchors))} have no radio the site "
                "can switch: a survey names landmarks by blinking them. Give them their radio "
                "address (PATCH /landmarks/{id} with 'radio') or unlock them"
            )
        anchors = [lm.id for lm in lms if lm.locked]
        if len(anchors) < 2:
            raise ConflictError(
                f"a survey needs two or more locked landmarks as anchors (far apart), "
                f"the map has {len(anchors)}: lock the surveyed ones first"
            )
        with self._lock:
            if self._state in ("driving", "solving"):
                raise ConflictError(f"a survey is already {self._state} with robot {self._robot}")
            runner = self.robots.get(robot)
            self._recording = self.recordings.start(robot, trigger="survey")
            given = [SurveyLandmark(lm.id, np.array([lm.x, lm.y, lm.z]), {}) for lm in lms]
            drive = LiveDrive(given, runner.camera, runner.geometry,
                              queue_frames=self.live.queue_frames)  # fmt: skip
            runner.add_tap(drive.add)
            self._drive, self._tap = drive, (robot, drive.add)
            self._state, self._robot, self._t0, self._count = "driving", robot, time.monotonic(), 0
            self._message, self._result, self._accepted = "", None, []
            self._drive_s, self._estimates, self._route = 0.0, 0, ()
            self._no_radio = no_radio
            if no_radio:
                self._message = _no_radio_text(no_radio)
            self._stop = stop = threading.Event()  # this drive's: an old thread keeps its own
            self._solver.start()
            blinker = BlinkDriver(
                self.leds, self.robots, robot, sorted(lm.id for lm in lms), self._settled,
                self.blinks, self._counted, anchors,
                frames_in_state=lambda lid, lit: drive.frames_since_switch(lid, lit=lit),
            )  # fmt: skip
            self._threads = [
                threading.Thread(target=blinker.run, args=(stop,), name="survey-blinks",
                                 daemon=True),
                threading.Thread(target=self._estimate, args=(drive, anchors, stop),
                                 name="survey-live", daemon=True),
            ]  # fmt: skip
            for t in self._threads:
                t.start()
        log.info("survey started by %s with robot %s", actor, robot)
        return self.status()

    # -- while driving -----------------------------------------------------------------------
    def _settled(self) -> set[int]:
        """Landmarks the live estimate already holds well (anchors identified, converged):
        they need no more blinks."""
        with self._lock:
            result = self._result if self._state == "driving" else None
        if result is None:
            return set()
        cfg = self.live
        return {
            e.id for e in result.landmarks.values()
            if landmark_state(e, cfg.converged_sigma_m) in ("anchor", "converged")
        }  # fmt: skip

    def _counted(self) -> None:
        with self._lock:
            self._count += 1

    def _estimate(self, drive: LiveDrive, anchors: list[int], stop: threading.Event) -> None:
        """Solve the drive so far every `solve_every_s` (or, when a solve took longer, as
        long after it ended as it took) until stopped."""
        cfg = self.live
        wait_s = cfg.solve_every_s
        while not stop.wait(wait_s):
            began = time.monotonic()
            snap = drive.snapshot()
            if len(snap.frame_t_ns) < 2 or len(snap.odom_t_ns) == 0:
                continue
            try:
                result = self._solver.drive(snap, anchors, cfg.bundle)
            except SolveCancelledError:
                return
            except ValueError as exc:  # e.g. an anchor not identified yet
                with self._lock:
                    if self._state == "driving" and not stop.is_set():
                        self._message = "estimating: " + str(exc).removeprefix("survey: ")
                        if self._no_radio:
                            self._message += "; " + _no_radio_text(self._no_radio)
                continue
            except Exception:  # never let the live estimate end the drive
                log.exception("survey: a live estimate failed")
                continue
            route = self._suggest(result)
            # at most half a core: the next solve waits at least as long as this one took
            wait_s = max(cfg.solve_every_s, time.monotonic() - began)
            with self._lock:
                if self._state != "driving" or stop.is_set():
                    return
                self._result, self._route = result, route
                self._drive_s = (int(snap.frame_t_ns[-1]) - int(snap.frame_t_ns[0])) / 1e9
                self._estimates += 1
                self._message = (
                    f"estimate {self._estimates}: {len(result.landmarks)} landmarks placed "
                    f"({time.monotonic() - began:.1f} s to solve)"
                )
                if drive.dropped:
                    self._message += f"; {drive.dropped} frames skipped (the server fell behind)"
                if self._no_radio:
                    self._message += "; " + _no_radio_text(self._no_radio)

    def _suggest(self, result: SurveyResult) -> tuple[tuple[float, float], ...]:
        """Waypoints over what `result` leaves uncertain (`survey.route.suggest_route`)."""
        robot = self._robot
        pose = None if robot is None else self.robots.latest(robot)
        lms = self.map.list()
        if pose is None or pose.x is None or pose.y is None or not lms:
            return ()
        xy, sig = [], []
        for lm in lms:
            e = result.landmarks.get(lm.id)
            xy.append((lm.x, lm.y) if e is None else (float(e.position[0]), float(e.position[1])))
            sig.append(math.nan if e is None else (0.0 if e.anchor else e.sigma_m))
        pos = np.array(xy)
        m = self.live.site_margin_m
        lo, hi = pos.min(axis=0) - m, pos.max(axis=0) + m
        route = suggest_route(
            (pose.x, pose.y), pos, sig, (float(lo[0]), float(hi[0]), float(lo[1]), float(hi[1])),
            visited_xy=result.trajectory[:, :2], config=self.live.route,
        )  # fmt: skip
        return tuple((float(x), float(y)) for x, y in route)

    def _end_drive(self) -> None:
        """Stop blinking, estimating and the tap (the caller set the state)."""
        self._stop.set()
        self._solver.cancel()  # a live solve still running is not wanted any more
        for t in self._threads:
            t.join(timeout=5.0)
        self._threads = []
        if self._tap is not None:
            name, tap = self._tap
            with contextlib.suppress(KeyError):  # the robot went away
                self.robots.get(name).remove_tap(tap)
            self._tap = None
        if self._drive is not None:
            self._drive.close()
            self._drive = None

    # -- the end -----------------------------------------------------------------------------
    def stop(self, *, actor: str) -> SurveyStatus:
        """End the drive and solve in a worker thread. ConflictError when not driving."""
        with self._lock:
            if self._state != "driving" or self._robot is None:
                raise ConflictError("no survey is driving")
            robot = self._robot
            self._state, self._route = "solving", ()  # the live estimate stays on show
            self._message = "solving the whole drive"
        self._end_drive()
        path = self.recordings.stop(robot) or self._recording
        threading.Thread(target=self._solve, args=(path,), name="survey-solve", daemon=True).start()
        log.info("survey stopped by %s: solving %s", actor, path)
        return self.status()

    def _solve(self, path: Path | None) -> None:
        try:
            if path is None:
                raise ValueError("the robot's recording was lost")
            with self._lock:
                skip = self._no_radio
            anchors = [a for a in self.anchors() if a not in skip]
            result = self._solver.recording(path, anchors, self.bundle, leave_out=skip)
        except SolveCancelledError:
            return
        except ValueError as exc:
            with self._lock:
                if self._state == "solving":  # not cancelled meanwhile
                    self._state, self._message = "failed", str(exc).removeprefix("survey: ")
                    self._result = None
            log.warning("survey failed: %s", exc)
            return
        with self._lock:
            if self._state != "solving":  # cancelled meanwhile
                return
            self._state, self._result = "done", result
            self._drive_s = float(result.trajectory_t_ns[-1] - result.trajectory_t_ns[0]) / 1e9
            self._message = f"{len(result.landmarks)} landmarks surveyed"

    def cancel(self, *, actor: str = "server") -> SurveyStatus:
        """Drop the survey: stop blinking and recording, nothing is solved or written, and
        the drive's recording is deleted (cancelled surveys once kept 1.6 GB in 25 minutes
        without a word). Idempotent."""
        with self._lock:
            robot, driving = self._robot, self._state in ("driving", "solving")
            folder = self._recording
            self._state, self._result, self._route, self._message = "idle", None, (), ""
            self._recording = None
        self._end_drive()
        if driving and robot is not None:
            with contextlib.suppress(KeyError):  # the robot went away
                self.recordings.stop(robot)
            if folder is not None:
                try:
                    self.recordings.catalog.delete(folder.name)
                except (NotFoundError, ConflictError, OSError) as exc:
                    log.warning("survey: its recording %s was not removed: %s", folder, exc)
        log.info("survey cancelled by %s", actor)
        return self.status()

    def status(self) -> SurveyStatus:
        with self._lock:
            result, cfg = self._result, self.live
            proposals: tuple[Proposal, ...] = ()
            if result is not None:
                proposals = tuple(
                    _proposal(e, landmark_state(e, cfg.converged_sigma_m))
                    for e in sorted(result.landmarks.values(), key=lambda e: e.id)
                )
            return SurveyStatus(
                self._state, self._robot, None if self._recording is None else str(self._recording),
                None if self._state == "idle" else time.monotonic() - self._t0, self._count,
                self._message, proposals, tuple(self._accepted),
                () if result is None else result.unseen, self._drive_s, self._estimates,
                self._route, cfg.converged_sigma_m, self._no_radio,
            )  # fmt: skip

    def accept(
        self, landmark_ids: list[int] | None, *, actor: str, include_flagged: bool = False
    ) -> SurveyStatus:
        """Write the proposals of `landmark_ids` (None: every one not flagged) into the map,
        each as its own audited, undoable edit, all in one transaction (a crash midway
        writes none): the final result, or while driving the latest live estimate. Nothing
        is written when any ID is refused.

        Raises:
            ConflictError: no estimate yet, or solving.
            ValueError: naming IDs that were not surveyed (or are anchors), given twice,
                flagged (without `include_flagged`) or locked in the map meanwhile.
        """
        with self._lock:
            result, state = self._result, self._state
        if state == "solving":
            raise ConflictError("the survey is solving: accept once it is done")
        if result is None:
            raise ConflictError(
                "no survey estimate to accept (start, drive until the first estimate, or stop "
                "and wait for done)"
            )
        free = {lid: e for lid, e in result.landmarks.items() if not e.anchor}
        if landmark_ids is None:
            chosen = sorted(lid for lid, e in free.items() if not e.flags)
        else:
            chosen = list(landmark_ids)
        _check_choice(chosen, free, include_flagged, {lm.id for lm in self.map.list() if lm.locked})
        edits = []
        for lid in chosen:
            e = free[lid]
            x, y, z = (float(v) for v in e.position)
            evidence = {
                "source": "survey",
                "views": e.views,
                "observations": e.observations,
                "rms_px": round(e.rms_px, 3),
            }
            edits.append(
                (
                    lid,
                    LandmarkUpdate(
                        x=x,
                        y=y,
                        z=z,
                        sigma_m=e.sigma_m,
                        covariance=e.covariance.tolist(),
                        evidence=evidence,
                    ),
                )
            )
        self.map.update_many(edits, actor=f"{actor} (survey)")  # all or none
        with self._lock:
            self._accepted += [lid for lid in chosen if lid not in self._accepted]
        return self.status()


def _no_radio_text(ids: tuple[int, ...]) -> str:
    """The status line's note on the landmarks a survey leaves out."""
    return (
        f"not surveyed (no radio, cannot blink): {', '.join(map(str, ids))}; give them their "
        "radio address to survey them"
    )


def _check_choice(
    chosen: list[int],
    free: dict[int, LandmarkEstimate],
    include_flagged: bool,
    locked: set[int],
) -> None:
    """ValueError naming every ID of `chosen` that cannot be accepted."""
    twice = sorted({i for i in chosen if chosen.count(i) > 1})
    if twice:
        raise ValueError(f"landmarks: {', '.join(map(str, twice))} given more than once")
    missing = sorted(set(chosen) - set(free))
    if missing:
        raise ValueError(
            f"landmarks: {', '.join(map(str, missing))} not surveyed (or anchors); "
            f"surveyed: {', '.join(map(str, sorted(free))) or 'none yet'}"
        )
    now_locked = sorted(set(chosen) & locked)
    if now_locked:
        raise ValueError(
            f"landmarks: {', '.join(map(str, now_locked))} are locked in the map (anchors): "
            "unlock them first to overwrite their surveyed positions"
        )
    flagged = [i for i in chosen if free[i].flags]
    if flagged and not include_flagged:
        names = "; ".join(f"{i}: {', '.join(free[i].flags)}" for i in flagged)
        raise ValueError(
            f"landmarks flagged by the survey ({names}): check them, or accept them anyway "
            "with include_flagged"
        )


def _proposal(e: LandmarkEstimate, state: LandmarkSurveyState) -> Proposal:
    moved = 0.0 if e.given is None else math.dist(e.position.tolist(), e.given.tolist())
    x, y, z = (float(v) for v in e.position)
    return Proposal(
        e.id, x, y, z, 0.0 if e.anchor else e.sigma_m, moved, e.views,
        e.rms_px if math.isfinite(e.rms_px) else 0.0, e.anchor, e.flags,
        (0.0, 0.0, 0.0) if e.anchor else e.ellipse(), state,
    )  # fmt: skip

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
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from live.survey.accept import accepted_edits, check_choice
from live.survey.blinks import BlinkDriver
from live.survey.estimator import RunningEstimate, route_over
from live.survey.live import LiveDrive, LiveSurveyConfig, landmark_state
from live.survey.solver import SolveCancelledError, SurveySolver
from live.survey.status import Proposal, State, SurveyStatus, no_radio_text, proposal
from localizer.events import Event
from store.errors import ConflictError, NotFoundError, UnavailableError
from survey.blinks import BlinkConfig
from survey.bundle import BundleConfig
from survey.incremental import IncrementalSurvey
from survey.result import SurveyResult
from survey.survey_map import SurveyLandmark

if TYPE_CHECKING:  # the facades are handed in (live.services); typing only
    from live.facades import LedsAndRadio, Recordings, Robots
    from store.landmarks import MapRepository

log = logging.getLogger(__name__)

__all__ = ["LiveSurvey", "Proposal", "SurveyStatus"]


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
        data_dir: Path | None = None,
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
        self._saved: IncrementalSurvey | None = None  # an interrupted drive's, to go on from
        self._running = RunningEstimate(data_dir, self._solver, self.live)
        self._resumed = False
        saved = self._running.saved()
        if saved is not None:  # the server restarted while a survey drove: its estimate kept
            state, extra = saved
            self._state, self._result = "interrupted", state.result
            robot = extra.get("robot")
            self._robot = robot if isinstance(robot, str) else None
            self._estimates = state.updates
            n = 0 if state.result is None else len(state.result.landmarks)
            self._message = (
                f"the server restarted during the drive: the live estimate is kept ({n} "
                "landmarks placed); start again with a robot to go on from it, or cancel"
            )
            self._saved = state

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
            resume = self._saved if self._state == "interrupted" else None
            self._saved, self._resumed = None, resume is not None
            self._running.begin(resume)
            given = [SurveyLandmark(lm.id, np.array([lm.x, lm.y, lm.z]), {}) for lm in lms]
            drive = LiveDrive(
                given, runner.camera, runner.geometry, queue_frames=self.live.queue_frames
            )
            runner.add_tap(drive.add)
            self._drive, self._tap = drive, (robot, drive.add)
            self._state, self._robot, self._t0, self._count = "driving", robot, time.monotonic(), 0
            self._message, self._accepted = "", []
            self._result = None if resume is None else resume.result
            self._drive_s, self._route = 0.0, ()
            self._estimates = 0 if resume is None else resume.updates
            self._no_radio = no_radio
            if no_radio:
                self._message = no_radio_text(no_radio)
            self._stop = stop = threading.Event()  # this drive's: an old thread keeps its own
            self._solver.start()
            blinker = BlinkDriver(
                self.leds,
                self.robots,
                robot,
                sorted(lm.id for lm in lms),
                self._settled,
                self.blinks,
                self._counted,
                anchors,
                frames_in_state=lambda lid, lit: drive.frames_since_switch(lid, lit=lit),
            )
            self._threads = [
                threading.Thread(
                    target=blinker.run, args=(stop,), name="survey-blinks", daemon=True
                ),
                threading.Thread(
                    target=self._estimate,
                    args=(drive, anchors, stop),
                    name="survey-live",
                    daemon=True,
                ),
            ]
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
            e.id
            for e in result.landmarks.values()
            if landmark_state(e, cfg.converged_sigma_m) in ("anchor", "converged")
        }

    def _counted(self) -> None:
        with self._lock:
            self._count += 1

    def _estimate(self, drive: LiveDrive, anchors: list[int], stop: threading.Event) -> None:
        """Update the running estimate every `solve_every_s` (or, when an update took
        longer, as long after it ended as it took) until stopped."""
        cfg = self.live
        wait_s = cfg.solve_every_s
        extra: dict[str, object] = {"robot": self._robot, "anchors": anchors}
        while not stop.wait(wait_s):
            began = time.monotonic()
            try:
                result = self._running.step(drive, anchors, extra)
            except SolveCancelledError:
                return
            except ValueError as exc:  # e.g. an anchor not identified yet
                with self._lock:
                    if self._state == "driving" and not stop.is_set():
                        self._message = "estimating: " + str(exc).removeprefix("survey: ")
                        if self._no_radio:
                            self._message += "; " + no_radio_text(self._no_radio)
                continue
            except Exception:  # never let the live estimate end the drive
                log.exception("survey: a live estimate failed")
                continue
            if result is None:
                continue
            route = self._suggest(result)
            # at most half a core: the next update waits at least as long as this one took
            wait_s = max(cfg.solve_every_s, time.monotonic() - began)
            with self._lock:
                if self._state != "driving" or stop.is_set():
                    return
                self._result, self._route = result, route
                t = result.trajectory_t_ns
                self._drive_s = (int(t[-1]) - int(t[0])) / 1e9 if len(t) else 0.0
                self._estimates += 1
                self._message = (
                    f"estimate {self._estimates}: {len(result.landmarks)} landmarks placed "
                    f"({time.monotonic() - began:.1f} s to update)"
                )
                if drive.dropped:
                    self._message += f"; {drive.dropped} frames skipped (the server fell behind)"
                if self._no_radio:
                    self._message += "; " + no_radio_text(self._no_radio)

    def _suggest(self, result: SurveyResult) -> tuple[tuple[float, float], ...]:
        """Waypoints over what `result` leaves uncertain (`live.survey.estimator.route_over`)."""
        robot = self._robot
        pose = None if robot is None else self.robots.latest(robot)
        if pose is None or pose.x is None or pose.y is None:
            return ()
        lms = {lm.id: (lm.x, lm.y) for lm in self.map.list()}
        return route_over(result, (pose.x, pose.y), lms, self.live)

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
        """End the drive and solve in a worker thread. ConflictError when not driving.

        A drive resumed after a restart ends with its running estimate (its recording holds
        only the drive since the restart; the estimate holds all of it)."""
        with self._lock:
            if self._state != "driving" or self._robot is None:
                raise ConflictError("no survey is driving")
            robot, resumed = self._robot, self._resumed
            self._state, self._route = "solving", ()  # the live estimate stays on show
            self._message = "solving the whole drive"
        self._end_drive()
        path = self.recordings.stop(robot) or self._recording
        if resumed:
            self._running.discard()
            with self._lock:
                if self._state == "solving":
                    n = 0 if self._result is None else len(self._result.landmarks)
                    self._state = "done" if self._result is not None else "failed"
                    self._message = (
                        f"{n} landmarks surveyed (the running estimate: the drive was resumed "
                        "after a restart)"
                        if n
                        else "no estimate was made"
                    )
            return self.status()
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
            self._running.discard()
            with self._lock:
                if self._state == "solving":  # not cancelled meanwhile
                    self._state, self._message = "failed", str(exc).removeprefix("survey: ")
                    self._result = None
            log.warning("survey failed: %s", exc)
            return
        self._running.discard()  # the final result replaces the running estimate
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
            self._recording, self._saved = None, None
        self._end_drive()
        self._running.discard()
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
                    proposal(e, landmark_state(e, cfg.converged_sigma_m))
                    for e in sorted(result.landmarks.values(), key=lambda e: e.id)
                )
            return SurveyStatus(
                self._state,
                self._robot,
                None if self._recording is None else str(self._recording),
                None if self._state == "idle" else time.monotonic() - self._t0,
                self._count,
                self._message,
                proposals,
                tuple(self._accepted),
                () if result is None else result.unseen,
                self._drive_s,
                self._estimates,
                self._route,
                cfg.converged_sigma_m,
                self._no_radio,
            )

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
        check_choice(chosen, free, include_flagged, {lm.id for lm in self.map.list() if lm.locked})
        edits = accepted_edits(chosen, free)
        self.map.update_many(edits, actor=f"{actor} (survey)")  # all or none
        with self._lock:
            self._accepted += [lid for lid in chosen if lid not in self._accepted]
        return self.status()

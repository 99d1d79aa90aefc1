"""The live survey: one robot records while the landmarks blink one at a time against the
lit ceiling, then `survey.solve_survey` places every landmark (docs/survey.md).

An admin starts it with a robot (`start`): the robot's frames, odometry and LED states are
recorded (`Recordings`), and a blink driver asks the LED coordinator, as the requester
"survey", to darken one landmark at a time (`survey.blinks.BlinkConfig` timing), as robots
identify themselves, so the other robots keep their fixes; it blinks the landmarks the
surveying robot expects in view, least blinked first. `stop` ends both and solves on the
recording in a worker thread; the locked landmarks are the anchors, every other landmark's map
position is its rough position. The result is a proposal: `accept` writes the chosen
landmarks' positions through the map's data layer (audited, undoable), never silently.
"""

from __future__ import annotations

import logging
import math
import threading
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, Literal

from localizer.events import LedRequest
from server.errors import ConflictError, NotFoundError, UnavailableError
from server.models import LandmarkUpdate
from survey.blinks import BlinkConfig
from survey.bundle import BundleConfig, solve_survey
from survey.drive import read_survey_drive, survey_problem
from survey.result import LandmarkEstimate, SurveyResult

if TYPE_CHECKING:  # the facades are handed in (server.services); typing only
    from server.crud.landmarks import MapRepository
    from server.facades import LedsAndRadio, Recordings, Robots

log = logging.getLogger(__name__)

SURVEY = "survey"
"""The LED coordinator's name for the survey's requests."""

State = Literal["idle", "driving", "solving", "done", "failed"]


@dataclass(frozen=True)
class Proposal:
    """One landmark's surveyed position (metres, world frame) against the map's."""

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


@dataclass(frozen=True)
class SurveyStatus:
    """Where the survey is.

    Attributes:
        state: idle, driving (recording and blinking), solving, done (proposals ready) or
            failed (`message` says why).
        robot: the surveying robot; recording: its recording folder.
        started_s: seconds since the drive started (None when idle).
        blinks: dark windows requested so far.
        proposals: the result, landmark by landmark (done only).
        accepted: landmarks whose proposal was written into the map.
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


class LiveSurvey:
    """Drive a survey with one robot (thread-safe; the blink driver runs in its own thread)."""

    def __init__(
        self,
        map: MapRepository,
        robots: Robots,
        leds: LedsAndRadio,
        recordings: Recordings,
        *,
        blinks: BlinkConfig | None = None,
        bundle: BundleConfig | None = None,
    ) -> None:
        self.map, self.robots, self.leds, self.recordings = map, robots, leds, recordings
        self.blinks = blinks or BlinkConfig()
        self.bundle = bundle or BundleConfig()
        self._lock = threading.Lock()
        self._state: State = "idle"
        self._robot: str | None = None
        self._recording: Path | None = None
        self._t0 = 0.0
        self._count = 0
        self._message = ""
        self._result: SurveyResult | None = None
        self._accepted: list[int] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def anchors(self) -> list[int]:
        """The locked landmarks: they keep their surveyed positions and fix the map's frame."""
        return [lm.id for lm in self.map.list() if lm.locked]

    def start(self, robot: str, *, actor: str) -> SurveyStatus:
        """Start recording `robot` and blinking. ConflictError while a survey drives or
        solves, or with fewer than two locked landmarks; UnavailableError without a radio;
        NotFoundError for an unknown robot."""
        coordinator = self.leds.coordinator
        if coordinator is None:
            raise UnavailableError("no radio: the site runs without a gateway, nothing can blink")
        names = self.robots.names()
        if robot not in names:
            raise NotFoundError(f"unknown robot {robot!r}; robots: {', '.join(sorted(names))}")
        anchors = self.anchors()
        if len(anchors) < 2:
            raise ConflictError(
                f"a survey needs two or more locked landmarks as anchors (far apart), "
                f"the map has {len(anchors)}: lock the surveyed ones first"
            )
        with self._lock:
            if self._state in ("driving", "solving"):
                raise ConflictError(f"a survey is already {self._state} with robot {self._robot}")
            self._recording = self.recordings.start(robot)
            self._state, self._robot, self._t0, self._count = "driving", robot, time.monotonic(), 0
            self._message, self._result, self._accepted = "", None, []
            self._stop.clear()
            ids = sorted(lm.id for lm in self.map.list())
            self._thread = threading.Thread(
                target=self._blink, args=(ids,), name="survey-blinks", daemon=True
            )
            self._thread.start()
        log.info("survey started by %s with robot %s", actor, robot)
        return self.status()

    def _blink(self, ids: list[int]) -> None:
        """One landmark dark at a time against the lit ceiling until stopped: of the
        landmarks the surveying robot expects in view (its localizer says which), the one
        blinked least so far; every landmark in turn while the robot has no pose."""
        coordinator = self.leds.coordinator
        robot = self._robot
        if coordinator is None or robot is None:
            return
        cfg = self.blinks
        dark_s = cfg.dark_frames * cfg.frame_period_s + cfg.radio_latency_s
        lit_s = cfg.lit_frames * cfg.frame_period_s + cfg.radio_latency_s
        blinked = dict.fromkeys(ids, 0)
        k = 0
        while not self._stop.is_set() and ids:
            pose = self.robots.latest(robot)
            near = [i for i in (pose.expected_ids if pose is not None else ()) if i in blinked]
            lid = min(near, key=lambda i: blinked[i]) if near else ids[k % len(ids)]
            k += not near
            blinked[lid] += 1
            coordinator.request(SURVEY, LedRequest(all_lit=True, dark=frozenset({lid})))
            with self._lock:
                self._count += 1
            # each window starts once the radio confirmed the switch, so that windows never
            # run into each other (the recording then names one dark landmark at a time)
            if not self._confirmed(lid, lit=False) or self._stop.wait(dark_s):
                break
            coordinator.request(SURVEY, LedRequest(all_lit=True))
            if not self._confirmed(lid, lit=True) or self._stop.wait(lit_s):
                break
        coordinator.request(SURVEY, LedRequest(all_lit=True))

    def _confirmed(self, landmark_id: int, *, lit: bool, timeout_s: float = 1.0) -> bool:
        """Wait until the gateway confirmed `landmark_id` lit (or dark), or `timeout_s`
        passed (a lost command, other requesters first). False when stopped."""
        gateway = self.leds.gateway
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            state = None if gateway is None else gateway.leds
            ready = state is not None and gateway is not None and not state.changing
            if ready and (landmark_id in state.lit_among(gateway.landmarks)) == lit:  # type: ignore[union-attr]
                return True
            if self._stop.wait(0.005):
                return False
        return not self._stop.is_set()

    def stop(self, *, actor: str) -> SurveyStatus:
        """End the drive and solve in a worker thread. ConflictError when not driving."""
        with self._lock:
            if self._state != "driving" or self._robot is None:
                raise ConflictError("no survey is driving")
            robot = self._robot
            self._state = "solving"
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        path = self.recordings.stop(robot) or self._recording
        threading.Thread(target=self._solve, args=(path,), name="survey-solve", daemon=True).start()
        log.info("survey stopped by %s: solving %s", actor, path)
        return self.status()

    def _solve(self, path: Path | None) -> None:
        try:
            if path is None:
                raise ValueError("the robot's recording was lost")
            drive = read_survey_drive(path)
            problem = survey_problem(drive, self.anchors())
            result = solve_survey(problem, self.bundle)
        except ValueError as exc:
            with self._lock:
                self._state, self._message = "failed", str(exc).removeprefix("survey: ")
            log.warning("survey failed: %s", exc)
            return
        with self._lock:
            self._state, self._result = "done", result
            self._message = f"{len(result.landmarks)} landmarks surveyed"

    def status(self) -> SurveyStatus:
        with self._lock:
            proposals: tuple[Proposal, ...] = ()
            if self._result is not None:
                proposals = tuple(
                    _proposal(e)
                    for e in sorted(self._result.landmarks.values(), key=lambda e: e.id)
                )
            return SurveyStatus(
                self._state, self._robot, None if self._recording is None else str(self._recording),
                None if self._state == "idle" else time.monotonic() - self._t0, self._count,
                self._message, proposals, tuple(self._accepted),
                () if self._result is None else self._result.unseen,
            )  # fmt: skip

    def accept(self, landmark_ids: list[int] | None, *, actor: str) -> SurveyStatus:
        """Write the proposals of `landmark_ids` (None: every one not flagged) into the map.
        ConflictError without a result; ValueError naming IDs that were not surveyed."""
        with self._lock:
            result = self._result
        if result is None:
            raise ConflictError("no survey result to accept (start, drive, stop, wait for done)")
        free = {lid: e for lid, e in result.landmarks.items() if not e.anchor}
        chosen = (
            [lid for lid, e in free.items() if not e.flags]
            if landmark_ids is None
            else landmark_ids
        )
        missing = sorted(set(chosen) - set(free))
        if missing:
            raise ValueError(
                f"landmarks: {', '.join(map(str, missing))} not surveyed (or anchors); "
                f"surveyed: {', '.join(map(str, sorted(free)))}"
            )
        done: list[int] = []
        for lid in chosen:
            x, y, z = (float(v) for v in free[lid].position)
            self.map.update(lid, LandmarkUpdate(x=x, y=y, z=z), actor=f"{actor} (survey)")
            done.append(lid)
        with self._lock:
            self._accepted.extend(i for i in done if i not in self._accepted)
        return self.status()

    def cancel(self) -> None:
        """Stop blinking and recording (shutdown); nothing is solved."""
        self._stop.set()
        with self._lock:
            robot, driving = self._robot, self._state == "driving"
            if driving:
                self._state = "idle"
        if driving and robot is not None:
            self.recordings.stop(robot)


def _proposal(e: LandmarkEstimate) -> Proposal:
    moved = 0.0 if e.given is None else math.dist(e.position.tolist(), e.given.tolist())
    x, y, z = (float(v) for v in e.position)
    return Proposal(
        e.id, x, y, z, 0.0 if e.anchor else e.sigma_m, moved, e.views,
        e.rms_px if math.isfinite(e.rms_px) else 0.0, e.anchor, e.flags,
    )  # fmt: skip

"""The live survey's running estimate: the surveying robot's events kept in memory while it
drives (`LiveDrive`), solved again every few seconds, and what each landmark's estimate says
(`landmark_state`).

The recording on disk stays the survey's record (the final solve after `stop` reads it); the
live estimate only needs the spots, the wheels and the LED states, which the robot's runner
hands over as it feeds its localizer (`RobotRunner.add_tap`). Frames are reduced to their spots
in a worker thread (`localizer.spots.detect_spots`), never on the robot's own thread.
"""

from __future__ import annotations

import bisect
import logging
import threading
from collections import deque
from dataclasses import dataclass, field
from typing import Literal

import numpy as np

from localizer.camera import CameraModel
from localizer.events import Event, FrameObserved, LedsChanged, OdometryMeasured, SpotsObserved
from localizer.robot import RobotGeometry
from localizer.spots import DetectionConfig, detect_spots
from localizer.types import FloatArray
from survey.drive import SurveyDrive
from survey.incremental import IncrementalConfig, window_of
from survey.problem import BundleConfig
from survey.result import LandmarkEstimate
from survey.route import RouteConfig
from survey.survey_map import SurveyLandmark

log = logging.getLogger(__name__)


LandmarkSurveyState = Literal["anchor", "converging", "converged", "flagged"]


@dataclass(frozen=True)
class LiveSurveyConfig:
    """Tuning of the live survey.

    Attributes:
        solve_every_s: a new live estimate is started this long after the previous one
            ended, or as long as the previous one took if that is longer (at most half a
            core), seconds.
        converged_sigma_m: a landmark whose 1-sigma uncertainty is at or under this counts
            as converged (2 sigma within the survey's 1 cm target), metres; it is no longer
            blinked.
        queue_frames: frames waiting for spot detection, at most (older ones are dropped
            when the machine falls behind: the tracker coasts over the gap).
        bundle: the estimator's tuning for the live solves (fewer iterations than the final
            one: it starts again a few seconds later anyway).
        route: the suggested route's tuning.
        site_margin_m: the route stays inside the landmarks' extent plus this, metres.
        incremental: the running estimate's window (`survey.incremental`): what is older
            than its lag is marginalised, so each update costs the same however long the
            drive.
    """

    solve_every_s: float = 4.0
    converged_sigma_m: float = 0.005
    queue_frames: int = 90
    bundle: BundleConfig = field(
        default_factory=lambda: BundleConfig(max_iterations=12, window_iterations=4)
    )
    route: RouteConfig = field(default_factory=RouteConfig)
    site_margin_m: float = 0.5
    incremental: IncrementalConfig = field(default_factory=IncrementalConfig)


def landmark_state(e: LandmarkEstimate, converged_sigma_m: float) -> LandmarkSurveyState:
    """What an estimate says: an anchor (locked, held), flagged (something looks wrong),
    converged (1-sigma at or under `converged_sigma_m`) or still converging."""
    if e.anchor:
        return "anchor"
    if e.flags:
        return "flagged"
    return "converged" if e.sigma_m <= converged_sigma_m else "converging"


class LiveDrive:
    """The surveying robot's events in memory, as a growing `SurveyDrive`.

    `add` is called on the robot's thread for every event it feeds its localizer (cheap: a
    frame is queued); a worker thread detects each frame's spots. `snapshot()` is the drive
    so far. `close()` stops the worker.
    """

    def __init__(
        self,
        landmarks: list[SurveyLandmark],
        camera: CameraModel,
        robot: RobotGeometry,
        *,
        detection: DetectionConfig | None = None,
        queue_frames: int = 90,
    ) -> None:
        self.landmarks, self.camera, self.robot = landmarks, camera, robot
        self.detection = detection or DetectionConfig()
        self._lock = threading.Lock()
        self._queue: deque[FrameObserved] = deque(maxlen=queue_frames)
        self._wake = threading.Event()
        self._closed = threading.Event()
        self._frame_t: list[int] = []
        self._spots: list[FloatArray] = []
        self._odom_t: list[int] = []
        self._odom_v: list[tuple[float, float]] = []
        self._leds: list[LedsChanged] = []
        self._recent_leds: deque[LedsChanged] = deque(maxlen=64)  # `changing` kept
        self._taken: deque[int] = deque(maxlen=256)  # times of the latest frames fed
        self.dropped = 0
        self._thread = threading.Thread(target=self._detect, name="survey-spots", daemon=True)
        self._thread.start()

    def add(self, event: Event) -> None:
        """One event of the robot (any thread; never blocks)."""
        with self._lock:
            if isinstance(event, FrameObserved | SpotsObserved):
                self._taken.append(event.t_ns)
            if isinstance(event, FrameObserved):
                if len(self._queue) == self._queue.maxlen:
                    self.dropped += 1
                self._queue.append(event)
                self._wake.set()
            elif isinstance(event, SpotsObserved):
                self._add_spots(event.t_ns, np.asarray(event.pixels, dtype=np.float64))
            elif isinstance(event, OdometryMeasured):
                if not self._odom_t or event.t_ns > self._odom_t[-1]:
                    self._odom_t.append(event.t_ns)
                    self._odom_v.append((event.v_left, event.v_right))
            elif isinstance(event, LedsChanged) and (
                not self._leds or event.t_ns >= self._leds[-1].t_ns
            ):
                self._leds.append(event.surely_dark_as_dark())  # as a recording keeps it
                self._recent_leds.append(event)

    def _add_spots(self, t_ns: int, pixels: FloatArray) -> None:
        if not self._frame_t or t_ns > self._frame_t[-1]:
            self._frame_t.append(t_ns)
            self._spots.append(pixels.reshape(-1, 2))

    def _detect(self) -> None:
        while not self._closed.is_set():
            self._wake.wait(0.5)
            while True:
                with self._lock:
                    if not self._queue:
                        self._wake.clear()
                        break
                    frame = self._queue.popleft()
                try:
                    pixels = detect_spots(np.asarray(frame.image, np.uint8), self.detection).pixels
                except Exception:  # a bad frame: skipped, as a recording's unreadable one
                    log.debug("survey: spot detection failed on a frame", exc_info=True)
                    continue
                with self._lock:
                    self._add_spots(frame.t_ns, np.asarray(pixels, dtype=np.float64))

    def frames_since_switch(self, landmark_id: int, *, lit: bool) -> int:
        """How many frames the robot took since `landmark_id` became surely `lit` (or surely
        dark: confirmed, no command in flight) and stayed so, 0 if it is not now: the frames
        of a blink's window a survey can use, however slowly the camera runs."""
        with self._lock:
            since: int | None = None
            for state in reversed(self._recent_leds):
                is_lit = state.all_lit or landmark_id in state.lit
                if landmark_id in state.changing or is_lit != lit:
                    break
                since = state.t_ns
            if since is None:
                return 0
            return sum(1 for t in self._taken if t > since)

    @property
    def frames(self) -> int:
        with self._lock:
            return len(self._frame_t)

    def snapshot(self, since_ns: int | None = None) -> SurveyDrive:
        """The drive so far (frames whose spots are known), from `since_ns` on when given
        (`survey.incremental.window_of`: the LED state in force then included)."""
        with self._lock:
            drive = SurveyDrive(
                self.landmarks,
                self.camera,
                self.robot,
                np.asarray(self._frame_t, dtype=np.int64),
                list(self._spots),
                np.asarray(self._odom_t, dtype=np.int64),
                np.asarray(self._odom_v, dtype=np.float64).reshape(-1, 2),
                list(self._leds),
                0,
            )
        return window_of(drive, since_ns)

    def forget_before(self, t_ns: int) -> None:
        """Drop what the running estimate no longer needs (frames, wheels and LED changes
        before `t_ns`, keeping the wheel sample and the LED state in force then): a long
        drive's memory stays that of its window. The recording keeps everything."""
        with self._lock:
            f = bisect.bisect_left(self._frame_t, t_ns)
            del self._frame_t[:f], self._spots[:f]
            o = max(bisect.bisect_left(self._odom_t, t_ns) - 1, 0)
            del self._odom_t[:o], self._odom_v[:o]
            before = [i for i, c in enumerate(self._leds) if c.t_ns <= t_ns]
            if before:
                del self._leds[: before[-1]]

    def close(self) -> None:
        self._closed.set()
        self._wake.set()
        self._thread.join(timeout=5.0)

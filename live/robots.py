"""One live robot: its sans-I/O localizer, the events fed to it and where its outputs go."""

from __future__ import annotations

import logging
import threading
from collections import deque
from collections.abc import Callable
from pathlib import Path
from typing import Any, Protocol

import numpy as np

from fleet.floor_fit import FloorFit
from live.black_box import BlackBox
from live.led_filter import only_landmarks
from live.pose_reasons import ReasonTally
from live.poses import PoseUpdate
from live.recording_queue import QueuedRecording, RecordingLimits, check_free_space
from localizer.camera import CameraModel
from localizer.config import LocalizerConfig
from localizer.events import (
    Event,
    FrameObserved,
    LedRequest,
    LedsChanged,
    Mode,
    NoPose,
    OdometryMeasured,
    Output,
    PoseEstimate,
    RelocalizeRequested,
    SpotsObserved,
)
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.robot import RobotGeometry
from recording.writer import RecordingWriter
from store.models import DEFAULT_FLOOR

log = logging.getLogger(__name__)


class LocalizerLike(Protocol):
    """What the runner needs of `localizer.Localizer`."""

    def handle(self, event: Event) -> list[Output]: ...
    def set_map(self, landmark_map: LandmarkMap) -> None: ...
    @property
    def mode(self) -> Mode: ...


def make_localizer(
    camera: CameraModel,
    landmark_map: LandmarkMap,
    robot: RobotGeometry,
    config: LocalizerConfig | None = None,
) -> LocalizerLike:
    """The project's localizer for one robot (`config`: None for the defaults)."""
    return Localizer(camera, landmark_map, robot, config)


class RobotRunner:
    """Feed one robot's localizer and route what comes out (thread-safe).

    Args:
        name: the robot's name.
        camera: its camera (intrinsics and mounting).
        geometry: its wheel geometry.
        localizer: a fresh localizer for this robot.
        publish: called with every `PoseUpdate` (pose bus).
        request_leds: called with (robot name, `LedRequest`) (the LED coordinator).
        source: "sim", "camera" or "remote".
        recent_frames: frames (or spot sets) kept for `frame_at`.
    """

    def __init__(
        self,
        name: str,
        camera: CameraModel,
        geometry: RobotGeometry,
        localizer: LocalizerLike,
        *,
        publish: Callable[[PoseUpdate], None],
        request_leds: Callable[[str, LedRequest], None],
        source: str = "sim",
        recent_frames: int = 12,
    ) -> None:
        self.name = name
        self.camera = camera
        self.geometry = geometry
        self.source = source
        self.localizer = localizer
        self._publish = publish
        self._request_leds = request_leds
        self._lock = threading.RLock()
        self.latest: PoseUpdate | None = None
        self.reasons = ReasonTally()  # why there is no fix now, and poses per reason
        self.black_box: BlackBox | None = None  # the last seconds, saved when it goes wrong
        self.last_fix_t_ns: int | None = None
        self.last_frame: FrameObserved | None = None
        self.recent: deque[FrameObserved | SpotsObserved] = deque(maxlen=recent_frames)
        self.frames = 0
        self.poses = 0
        self.errors = 0
        self.recorder: QueuedRecording | None = None
        self.recording_limits = RecordingLimits()
        self.on_recording_stopped: Callable[[str, Path, str], None] | None = None
        self._taps: tuple[Callable[[Event], None], ...] = ()
        self.on_mode_change: Callable[[str, Mode, Mode], None] | None = None
        self._mode: Mode = localizer.mode
        self._pending: deque[Event] = deque()
        self._leds_in_force: LedsChanged | None = None  # the last LED state fed
        self.floor = DEFAULT_FLOOR
        """The floor whose map the localizer holds (every pose names it)."""
        self.map_version = 0
        """The version of that floor's map the localizer holds."""
        self._map_ids: frozenset[int] | None = None  # None: every LED is the map's
        self.floor_fit: FloorFit | None = None
        """Whether its view still fits its floor's map (a site with several floors; set by
        `live.floor_watch`): while its floor is unknown its poses are withheld."""

    @property
    def mode(self) -> Mode:
        return self._mode

    def post(self, event: Event) -> None:
        """Queue an event from another thread (LED changes): it is fed before the next event
        of a later or equal time, so the localizer sees events in time order."""
        self._pending.append(event)

    def handle(self, event: Event) -> None:
        """Feed one event (and the posted events due before it); a localizer exception is
        logged and counted, never raised."""
        with self._lock:
            while self._pending and self._pending[0].t_ns <= event.t_ns:
                self._feed(self._pending.popleft())
            self._feed(event)

    def _feed(self, event: Event) -> None:
        with self._lock:
            if isinstance(event, FrameObserved):
                self.frames += 1
                self.last_frame = event
            if isinstance(event, FrameObserved | SpotsObserved):
                self.recent.append(event)
            self._record(event)
            own = self._own(event)
            if self.black_box is not None:
                self.black_box.add_event(own)
            for tap in self._taps:
                tap(event)
            try:
                outputs = self.localizer.handle(own)
            except Exception:
                self.errors += 1
                log.exception(
                    "robot %s: localizer failed on %s",
                    self.name,
                    type(event).__name__,
                    extra={"robot": self.name},
                )
                return
            if isinstance(event, LedsChanged):
                self._leds_in_force = event
            if isinstance(event, FrameObserved):
                self._record_pose(outputs)
            for out in outputs:
                self._route(out)
            old, self._mode = self._mode, self.localizer.mode
        if old != self._mode and self.on_mode_change is not None:
            self.on_mode_change(self.name, old, self._mode)

    def _own(self, event: Event) -> Event:
        """The event as the localizer may see it: an LED state names only its map's
        landmarks (an LED switched on another floor is no landmark of this one)."""
        if self._map_ids is None or not isinstance(event, LedsChanged):
            return event
        return only_landmarks(event, self._map_ids)

    def _route(self, out: Output) -> None:
        fit = self.floor_fit
        if isinstance(out, PoseEstimate | NoPose) and fit is not None and fit.observe(out):
            # its view does not fit its floor's map: no pose on that map goes out
            self.latest = PoseUpdate(
                self.name,
                out.t_ns,
                out.mode,
                floor=self.floor,
                map_version=self.map_version,
                floor_unknown=True,
            )
            self._publish(self.latest)
            return
        if isinstance(out, PoseEstimate):
            upd = PoseUpdate.from_estimate(
                self.name, out, floor=self.floor, map_version=self.map_version
            )
            self.latest = upd
            self.reasons.note(upd)
            if self.black_box is not None:
                self.black_box.add_pose(out)
            self.poses += 1
            if out.mode == "landmark":
                self.last_fix_t_ns = out.t_ns
            self._publish(upd)
        elif isinstance(out, NoPose):
            none = PoseUpdate.from_no_pose(
                self.name, out, floor=self.floor, map_version=self.map_version
            )
            self.reasons.note(none)
            if self.black_box is not None:
                self.black_box.add_pose(out)
            self._publish(none)
        elif isinstance(out, LedRequest):
            self._request_leds(self.name, out)

    def frame_at(self, t_ns: int) -> FrameObserved | SpotsObserved | None:
        """The frame (or spots) taken at `t_ns`, when it is among the last few."""
        for event in reversed(self.recent):
            if event.t_ns == t_ns:
                return event
        return None

    def relocalize(self, t_ns: int, near: tuple[float, float, float] | None = None) -> None:
        """The operator's request: forget the pose and identify again (near a pose)."""
        self.handle(RelocalizeRequested(t_ns, near))

    def set_map(self, landmark_map: LandmarkMap, map_version: int | None = None) -> None:
        """A new version of the map of the robot's floor."""
        with self._lock:
            self.localizer.set_map(landmark_map)
            self._map_ids = frozenset(int(i) for i in landmark_map.ids)
            if map_version is not None:
                self.map_version = map_version

    def set_floor(
        self,
        floor: str,
        landmark_map: LandmarkMap,
        map_version: int,
        t_ns: int,
        near: tuple[float, float, float] | None = None,
    ) -> None:
        """The robot is now on `floor` (out of the lift): its localizer takes that floor's
        map and identifies again, near (x, y, theta) of that floor when given (the lift's
        node). Every pose from here on names the new floor; none of the old floor's pose
        is carried over (the pose is forgotten)."""
        with self._lock:
            self.floor, self.map_version = floor, map_version
            if self.floor_fit is not None:
                self.floor_fit.known()
            self.set_map(landmark_map)
            self.latest = None
            self.handle(RelocalizeRequested(t_ns, near))

    # -- taps and recording ------------------------------------------------------------------
    def add_tap(self, tap: Callable[[Event], None]) -> None:
        """Hand every event fed to the localizer (in time order, LED changes included) to
        `tap` too, on the feeding thread: it must return at once (the live survey queues)."""
        with self._lock:
            self._taps = (*self._taps, tap)

    def remove_tap(self, tap: Callable[[Event], None]) -> None:
        with self._lock:
            self._taps = tuple(t for t in self._taps if t is not tap)

    def start_recording(self, root: Path, landmark_records: list[dict[str, Any]]) -> None:
        """Record this robot's frames, odometry, LED changes and live poses to a recording
        folder; leds.csv starts with the LED state in force (a replay then knows what was lit
        before the first change)."""
        with self._lock:
            if self.recorder is not None:
                raise ValueError(f"robot {self.name!r} is already recording")
            check_free_space(root, self.recording_limits)
            writer = RecordingWriter(root, self.camera, self.geometry, landmark_records)
            rec = QueuedRecording(
                writer, self.recording_limits, self._recording_stopped, name=self.name
            )
            if self._leds_in_force is not None:
                rec.add_leds(self._leds_in_force)
            self.recorder = rec

    def _recording_stopped(self, reason: str) -> None:
        """The recording stopped by itself (writer thread): forget it and say why."""
        with self._lock:
            rec = self.recorder
            if rec is not None and rec.stopped is not None:
                self.recorder = None
        if rec is not None and self.on_recording_stopped is not None:
            self.on_recording_stopped(self.name, rec.root, reason)

    def stop_recording(self) -> Path | None:
        with self._lock:
            rec, self.recorder = self.recorder, None
        if rec is None:
            return None
        return rec.close()

    def _record_pose(self, outputs: list[Output]) -> None:
        """The localizer's answer to a recorded frame, to live_poses.csv (queued)."""
        rec = self.recorder
        est = next((o for o in outputs if isinstance(o, PoseEstimate | NoPose)), None)
        if rec is not None and est is not None:
            rec.add_pose(est)

    def _record(self, event: Event) -> None:
        """Queue `event` for the recording (the writer thread writes it)."""
        rec = self.recorder
        if rec is None:
            return
        if isinstance(event, FrameObserved):
            rec.add_frame(event.t_ns, np.ascontiguousarray(event.image))
        elif isinstance(event, OdometryMeasured):
            rec.add_odometry(event.t_ns, event.v_left, event.v_right)
        elif isinstance(event, LedsChanged):
            rec.add_leds(event)

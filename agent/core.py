"""The agent's localization loop, without the network: the same sans-I/O `Localizer` the
server runs, fed from the robot's sensors and the site's LED states, and the messages it
produces (poses, LED requests, VDA 5050 visualization).

Time order: a frame must meet every LED state of its time. LED states travel over the
network, frames do not, so sensor samples wait `hold_s` (`reorder_hold_s`) in a reorder
buffer and are fed with the LED states merged in time order; the simulated source is stepped
that far behind real time too. A state that arrives later than that is fed at once and
counted (`late_leds`). A sensor stream that falls behind (its thread or its transport
stalled) holds the feeding back, up to `input_wait_s`, so that what it delivers late is
still fed in order rather than dropped (`SensorSource.complete_until`).

Thread-safety: `on_*` methods may be called from the network thread while `tick` runs on the
sensor thread; they only queue.
"""

from __future__ import annotations

import heapq
import itertools
import json
import logging
import threading
from collections import deque
from dataclasses import dataclass
from typing import Literal, Protocol, TextIO

import numpy as np
import numpy.typing as npt

from agent.floors import Floors
from agent.timebase import TimeBase
from fleet.payloads import (
    AgentSource,
    AgentStatus,
    CommandMessage,
    FloorMessage,
    LedRequestMessage,
    LedStateMessage,
    MapMessage,
    PoseMessage,
)
from fleet.vda5050 import HeaderIds, visualization_message
from localizer.camera import CameraModel, sensor_from_camera
from localizer.events import (
    Event,
    FrameObserved,
    ImuMeasured,
    LedRequest,
    Mode,
    NoPose,
    OdometryMeasured,
    PoseEstimate,
    RelocalizeRequested,
    SpotsObserved,
)
from localizer.landmark_map import LandmarkMap
from localizer.localizer import Localizer
from localizer.robot import RobotGeometry
from localizer.spots import DetectionConfig, detect_spots

log = logging.getLogger(__name__)
NS = 1_000_000_000
PREMAP_MOTION_EVENTS = 60_000
"""Motion samples kept until the first map arrives (ten minutes of 100 Hz wheels)."""

OutKind = Literal["pose", "led_request", "visualization"]


class CoreObserver(Protocol):
    """Told of every map the localizer takes and every pose (or its absence) it computes,
    on the sensor thread, unthrottled (the ROS 2 outputs, `agent.ros2_agent`)."""

    def on_map(self, landmark_map: LandmarkMap) -> None: ...
    def on_pose(self, output: PoseEstimate | NoPose) -> None: ...


class SensorSource(Protocol):
    """What the agent's sensors give: the robot's camera and wheels, simulated or real."""

    @property
    def camera(self) -> CameraModel: ...
    @property
    def geometry(self) -> RobotGeometry: ...
    def step(self, t_ns: int) -> list[Event]: ...
    def complete_until(self, t_ns: int, max_wait_ns: int) -> int:
        """`t_ns`, or earlier while one of its streams, less than `max_wait_ns` behind, has
        not delivered up to it yet."""
        ...

    def apply_leds(self, t_ns: int, lit: frozenset[int] | None) -> None: ...
    def true_pose_at(self, t_ns: int) -> tuple[float, float, float] | None: ...
    @property
    def start_pose(self) -> tuple[float, float, float] | None: ...


@dataclass(frozen=True)
class AgentConfig:
    """Tuning of an agent.

    Attributes:
        name: the robot's name (its VDA 5050 serial number).
        manufacturer: VDA 5050 manufacturer.
        source: what feeds it ("sim", "sim-light", "camera").
        reorder_hold_s: how long sensor samples wait for LED states of their time, seconds
            (more than the network's one-way delay to the broker and back).
        input_wait_s: how long a sensor stream that fell behind is waited for, seconds
            (its samples are then fed in order when they arrive; a stream further behind
            is taken for stopped and is no longer waited for).
        pose_rate_hz: irloc pose messages per second at most (a mode change always goes at
            once); 0: one per frame.
        visualization_rate_hz: VDA 5050 visualization messages per second at most.
        start_known: the robot knows where it starts (a dock): the localizer is given the
            source's `start_pose` as a prior, and the map confirms it without LED probes
            when the landmarks in view agree.
        spots_period_s: a pose message carries its frame's spots (for the server's map
            upkeep) at most this often, seconds (0: never), and only for a confident frame:
            landmark mode, two or more landmarks, 1-sigma position within
            `spots_max_sigma_m` metres.
        floor: the floor it starts on, when it knows (a simulated robot's; `--floor`):
            it takes that floor's map until the site tells it its floor
            (`agents/<name>/floor`), and says so in its status; None: the site's default
            floor's map until told.
    """

    name: str
    manufacturer: str = "irloc"
    source: AgentSource = "sim"
    reorder_hold_s: float = 0.03
    input_wait_s: float = 1.0
    pose_rate_hz: float = 10.0
    visualization_rate_hz: float = 1.0
    start_known: bool = False
    spots_period_s: float = 1.0
    spots_max_sigma_m: float = 0.05
    floor: str | None = None


@dataclass(frozen=True)
class Outgoing:
    kind: OutKind
    payload: bytes


class AgentCore:
    """One robot's localizer and its messages (see the module docstring)."""

    def __init__(
        self,
        config: AgentConfig,
        source: SensorSource,
        timebase: TimeBase,
        *,
        truth_log: TextIO | None = None,
    ) -> None:
        self.config = config
        self.truth_log = truth_log
        self.source = source
        self.time = timebase
        self.localizer: Localizer | None = None
        self.map_id: str | None = None
        self.map_floor: str | None = None
        self.map_version: int | None = None
        self.mode: Mode = "identifying"
        self.frames = 0
        self.poses = 0
        self.errors = 0
        self.late_leds = 0
        self.led_states = 0
        self._inbox: list[MapMessage | LedStateMessage | CommandMessage | FloorMessage] = []
        self._inbox_lock = threading.Lock()
        self._heap: list[tuple[int, int, Event]] = []
        self._count = itertools.count()
        self._fed_t_ns = 0
        self._seq = itertools.count()
        self._headers = HeaderIds()
        self._last_pose_mono = -(10**18)
        self._last_vis_mono = -(10**18)
        self._last_spots_mono = -(10**18)
        self._last_frame: FrameObserved | SpotsObserved | None = None
        self._last_mode_sent: Mode | None = None
        self._last_led: tuple[int, int] | None = None
        self.observers: list[CoreObserver] = []
        # the motion before the first map: a dock prior is valid at the first sample, so the
        # robot's motion until the map arrives is replayed into the new localizer
        self._first_t_ns: int | None = None
        self._premap_motion: deque[OdometryMeasured | ImuMeasured]
        self._premap_motion = deque(maxlen=PREMAP_MOTION_EVENTS)
        self._premap_overflow = False
        self.floors = Floors(config.name, config.floor)

    # -- from the network (any thread) -------------------------------------------------------
    def on_map(self, msg: MapMessage) -> None:
        self._post(msg)

    def on_leds(self, msg: LedStateMessage) -> None:
        self._post(msg)

    def on_command(self, msg: CommandMessage) -> None:
        self._post(msg)

    def on_floor(self, msg: FloorMessage) -> None:
        """The floor the site has this robot on (`agents/<name>/floor`)."""
        self._post(msg)

    def _post(self, msg: MapMessage | LedStateMessage | CommandMessage | FloorMessage) -> None:
        with self._inbox_lock:
            self._inbox.append(msg)

    # -- the sensor loop ------------------------------------------------------------------------
    def tick(self, now_mono_ns: int) -> list[Outgoing]:
        """Take what arrived, step the sensors to `now - hold` (or as far as every sensor
        stream delivered), feed the localizer in time order; the messages to send."""
        hold_ns = round(self.config.reorder_hold_s * NS)
        wait_ns = round(self.config.input_wait_s * NS)
        horizon = self.source.complete_until(now_mono_ns - hold_ns, wait_ns)
        with self._inbox_lock:
            inbox, self._inbox = self._inbox, []
        for msg in inbox:
            self._take(msg, horizon)
        for event in self.source.step(horizon):
            self._push(event)
        out: list[Outgoing] = []
        while self._heap and self._heap[0][0] <= horizon:
            _, _, event = heapq.heappop(self._heap)
            out += self._feed(event, now_mono_ns)
        return out

    def _push(self, event: Event) -> None:
        heapq.heappush(self._heap, (event.t_ns, next(self._count), event))

    def _take(
        self, msg: MapMessage | LedStateMessage | CommandMessage | FloorMessage, horizon: int
    ) -> None:
        if isinstance(msg, MapMessage):
            if self.floors.on_map(msg, self.map_floor):
                self._set_map(msg)
        elif isinstance(msg, FloorMessage):
            to_take = self.floors.on_floor(msg, self.map_floor)
            if to_take is not None:
                self._set_map(to_take)
        elif isinstance(msg, LedStateMessage):
            key = (msg.seq, msg.t_ns)
            if key == self._last_led:
                return  # a retained copy of the state already taken (after a reconnect)
            self._last_led = key
            self.led_states += 1
            t = self.time.mono_from_site(msg.t_ns)
            if t < self._fed_t_ns:
                self.late_leds += 1
                t = self._fed_t_ns
            self.source.apply_leds(t, None if msg.all_lit else frozenset(msg.lit))
            self._push(msg.event(t))
        else:
            self._push(RelocalizeRequested(max(horizon, self._fed_t_ns), msg.near))

    def _set_map(self, msg: MapMessage) -> None:
        again, near = self.floors.reidentify()
        if msg.map_id == self.map_id and not again:
            return
        lmap = LandmarkMap.from_records(msg.records(), source=f"map {msg.map_id}")
        if self.localizer is None:
            self.localizer = Localizer(self.source.camera, lmap, self.source.geometry)
            self._start_prior(self.localizer)
            again = near is not None  # a fresh localizer identifies anyway
        else:
            self.localizer.set_map(lmap)
        if again:  # changed floors: nothing of the old floor's pose is kept (before any
            # frame still queued meets the new map)
            self._push(RelocalizeRequested(self._fed_t_ns, near))
        self.map_id = msg.map_id
        for observer in self.observers:
            observer.on_map(lmap)
        self.map_floor, self.map_version = msg.floor, msg.version
        log.info(
            "%s: map %s of floor %s, version %d (%d landmarks)",
            self.config.name,
            msg.map_id,
            msg.floor,
            msg.version,
            len(msg.landmarks),
        )

    def _start_prior(self, localizer: Localizer) -> None:
        """The dock prior (`start_known`), stamped at the first sample it holds for, and
        the wheel and IMU motion since, so a map that arrives late (a slow broker, a loaded
        machine) does not pin the start pose on a robot that already drove off."""
        start = self.source.start_pose
        motion = list(self._premap_motion)
        self._premap_motion.clear()
        if not self.config.start_known or start is None:
            return
        if self._premap_overflow:
            log.warning(
                "%s: the map came after more than %d motion samples: the dock prior is "
                "stale and not used (the robot identifies landmarks instead)",
                self.config.name,
                PREMAP_MOTION_EVENTS,
            )
            return
        localizer.set_initial_pose(*start, self._first_t_ns or self._fed_t_ns)
        for event in motion:
            localizer.handle(event)  # motion only: no pose or LED request worth sending

    def _feed(self, event: Event, now_mono: int) -> list[Outgoing]:
        self._fed_t_ns = max(self._fed_t_ns, event.t_ns)
        if self._first_t_ns is None:
            self._first_t_ns = event.t_ns
        if isinstance(event, FrameObserved | SpotsObserved):
            self.frames += 1
            self._last_frame = event
        if self.localizer is None:  # no map yet: nothing to localize on, motion kept
            if isinstance(event, OdometryMeasured | ImuMeasured):
                full = len(self._premap_motion) == self._premap_motion.maxlen
                self._premap_overflow |= full
                self._premap_motion.append(event)
            return []
        try:
            outputs = self.localizer.handle(event)
        except Exception:
            self.errors += 1
            log.exception("%s: localizer failed on %s", self.config.name, type(event).__name__)
            return []
        self.mode = self.localizer.mode
        out: list[Outgoing] = []
        for o in outputs:
            if isinstance(o, LedRequest):
                out.append(Outgoing("led_request", LedRequestMessage.from_request(o).encode()))
            else:
                for observer in self.observers:
                    observer.on_pose(o)
                out += self._pose_out(o, now_mono)
        return out

    def _pose_out(self, o: PoseEstimate | NoPose, now_mono: int) -> list[Outgoing]:
        cfg = self.config
        unknown = self.floors.withhold(o)  # every frame, sent or not
        mode_changed = o.mode != self._last_mode_sent
        # 0.8: a frame a little early still goes (a 10 Hz camera gives 10 Hz of poses)
        elapsed = now_mono - self._last_pose_mono
        due = cfg.pose_rate_hz <= 0 or elapsed * cfg.pose_rate_hz >= 0.8 * NS
        if not (mode_changed or due):
            return []
        self._last_pose_mono = now_mono
        self._last_mode_sent = o.mode
        t_site = self.time.site_from_mono(o.t_ns)
        wall = self.time.site_now_ns()
        seq = next(self._seq)
        out: list[Outgoing] = []
        if self.floors.waiting(self.map_floor):  # no pose on the old floor's map
            msg = PoseMessage(
                seq=seq, t_ns=t_site, wall_ns=wall, mode="identifying", floor=self.floors.wanted
            )
        elif unknown:  # its view does not fit its floor's map: no pose on it
            msg = PoseMessage(
                seq=seq,
                t_ns=t_site,
                wall_ns=wall,
                mode=o.mode,
                floor=self.map_floor,
                map_version=self.map_version,
                floor_unknown=True,
            )
        elif isinstance(o, PoseEstimate):
            self.poses += 1
            msg = PoseMessage.from_estimate(
                seq, o, t_site, wall, self._spots_for(o, now_mono)
            ).model_copy(update={"floor": self.map_floor, "map_version": self.map_version})
            self._log_truth(o, t_site)
        else:
            msg = PoseMessage.from_no_pose(seq, o, t_site, wall).model_copy(
                update={"floor": self.map_floor, "map_version": self.map_version}
            )
        out.append(Outgoing("pose", msg.encode()))
        if mode_changed or (now_mono - self._last_vis_mono) * cfg.visualization_rate_hz >= 0.8 * NS:
            self._last_vis_mono = now_mono
            out.append(Outgoing("visualization", self.visualization(msg)))
        return out

    def _spots_for(self, o: PoseEstimate, now_mono: int) -> npt.NDArray[np.float64] | None:
        """The spots of the estimate's frame when they go with it (`spots_period_s`)."""
        cfg = self.config
        frame = self._last_frame
        if (
            cfg.spots_period_s <= 0
            or frame is None
            or frame.t_ns != o.t_ns
            or o.mode != "landmark"
            or len(o.landmark_ids) < 2
            or (now_mono - self._last_spots_mono) < cfg.spots_period_s * NS
        ):
            return None
        cov = np.asarray(o.covariance, dtype=np.float64)
        if float(np.sqrt(max(np.linalg.eigvalsh(cov[:2, :2])[-1], 0.0))) > cfg.spots_max_sigma_m:
            return None
        self._last_spots_mono = now_mono
        if isinstance(frame, SpotsObserved):
            return np.asarray(frame.pixels, dtype=np.float64).reshape(-1, 2)
        return detect_spots(frame.image, DetectionConfig()).pixels

    def _log_truth(self, o: PoseEstimate, t_site: int) -> None:
        """`t_ns,mode,x,y,theta,true_x,true_y,true_theta` for a simulated robot (tests)."""
        truth = self.source.true_pose_at(o.t_ns) if self.truth_log is not None else None
        if truth is None or self.truth_log is None:
            return
        self.truth_log.write(
            f"{t_site},{o.mode},{o.x:.5f},{o.y:.5f},{o.theta:.6f},"
            f"{truth[0]:.5f},{truth[1]:.5f},{truth[2]:.6f}\n"
        )
        self.truth_log.flush()

    def visualization(self, msg: PoseMessage) -> bytes:
        """The VDA 5050 visualization message of a pose message."""
        pose = (
            None
            if msg.x is None or msg.y is None or msg.theta is None
            else (msg.x, msg.y, msg.theta)
        )
        vis = visualization_message(
            self._headers.take(self.config.name, "visualization"),
            msg.wall_ns,
            self.config.manufacturer,
            self.config.name,
            map_id=self.map_floor or self.map_id or "",  # VDA 5050 mapId: the floor
            mode=msg.mode,
            pose=pose,
            covariance=msg.covariance(),
            quality=msg.quality,
            deviation_m=msg.deviation_m,
        )
        return json.dumps(vis, separators=(",", ":")).encode()

    def status(self, clock_offset_ns: int | None, clock_error_ns: int | None) -> AgentStatus:
        return AgentStatus(
            source=self.config.source,
            camera=sensor_from_camera(self.source.camera),
            wheel_base=self.source.geometry.wheel_base,
            max_speed=self.source.geometry.max_speed,
            mode=self.mode,
            clock_offset_ns=clock_offset_ns,
            clock_error_ns=clock_error_ns,
            frames=self.frames,
            poses=self.poses,
            errors=self.errors,
            map_id=self.map_id,
            map_version=self.map_version if self.map_id is not None else None,
            floor=self.map_floor or self.floors.wanted,
        )

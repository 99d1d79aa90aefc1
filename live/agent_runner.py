"""A robot whose localizer runs on the robot (`irloc agent`, source `agent`): its poses arrive
over MQTT (`live.mqtt_bridge`) and reach the pose bus, the REST API, the WebSocket stream
and the viewer like those of the robots localized here.

It is a `RobotRunner` for everything that reads robots; what differs: LED states and the map
go to the agent over MQTT (not through `post`/`set_map`), relocalizing is a command sent to
the agent, and there are no frames here to record.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

import numpy as np

from fleet.clock import ClockEstimate
from fleet.payloads import AgentStatus, PoseMessage
from live.poses import PoseUpdate
from live.robots import RobotRunner
from localizer.camera import camera_from_sensor
from localizer.events import Event, Mode, SpotsObserved
from localizer.landmark_map import LandmarkMap
from localizer.robot import RobotGeometry


class _OnTheRobot:
    """The localizer of an agent as the runner sees it: it runs on the robot, so the runner
    only knows the mode the agent last reported."""

    def __init__(self, mode: Mode) -> None:
        self.mode: Mode = mode

    def handle(self, event: Any) -> list[Any]:
        return []

    def set_map(self, landmark_map: LandmarkMap) -> None:
        return None


class AgentRunner(RobotRunner):
    """One agent's robot on the server.

    Args:
        name: the robot's name (its VDA 5050 serial number).
        status: the agent's status message (camera, wheels, clock).
        publish: the pose bus.
        send_command: sends (robot, command dict) to the agent (relocalize).
        site_from_wall: turns a site server wall-clock time (ns) into the site clock.
    """

    def __init__(
        self,
        name: str,
        status: AgentStatus,
        *,
        publish: Callable[[PoseUpdate], None],
        send_command: Callable[[str, tuple[float, float, float] | None], None],
        site_from_wall: Callable[[int], int],
    ) -> None:
        camera = camera_from_sensor(status.camera, source=f"agent {name} status camera")
        geometry = RobotGeometry(status.wheel_base, status.max_speed)
        self._remote = _OnTheRobot(status.mode)
        super().__init__(
            name,
            camera,
            geometry,
            self._remote,
            publish=publish,
            request_leds=lambda robot, req: None,
            source="agent",
        )
        self._send_command = send_command
        self._site_from_wall = site_from_wall
        self.connected = True
        self.status = status
        self.clock: ClockEstimate | None = None
        self.clock_within_tolerance: bool | None = None
        self.last_seq: int | None = None
        self.lost_messages = 0
        self.update_status(status)

    def update_status(self, status: AgentStatus) -> None:
        self.status = status
        self.frames = status.frames
        self.errors = status.errors
        if status.clock_offset_ns is not None and status.clock_error_ns is not None:
            self.clock = ClockEstimate(status.clock_offset_ns, status.clock_error_ns, 0, 1)

    def receive(self, msg: PoseMessage) -> PoseUpdate:
        """One pose from the agent: onto the pose bus (times turned to the site clock)."""
        if self.last_seq is not None and msg.seq > self.last_seq + 1:
            self.lost_messages += msg.seq - self.last_seq - 1
        self.last_seq = msg.seq
        if msg.floor is not None and msg.floor != self.floor and msg.x is not None:
            # on another floor's map than the site has it on (it has not taken the floor
            # it was told yet): no pose of one floor goes out as another's
            msg = msg.model_copy(
                update={
                    "x": None,
                    "y": None,
                    "theta": None,
                    "cov": None,
                    "spots": None,
                    "floor": self.floor,
                    "map_version": self.map_version,
                }
            )
            withheld = True
        else:
            withheld = False
        cov = msg.covariance()
        upd = PoseUpdate(
            self.name,
            self._site_from_wall(msg.t_ns),
            msg.mode,
            msg.x,
            msg.y,
            msg.theta,
            cov,
            tuple(msg.lm),
            msg.wall_ns,
            expected_ids=tuple(msg.ex or ()),
            floor=msg.floor if msg.floor is not None else self.floor,
            map_version=msg.map_version if msg.map_version is not None else self.map_version,
            floor_unknown=withheld or bool(msg.floor_unknown),
            quality=msg.quality,
            deviation_m=msg.deviation_m,
            reason=msg.reason,
            reason_text=msg.reason_text or "",
        )
        self.reasons.note(upd)
        if msg.spots is not None:  # a confident frame's spots: map upkeep takes them
            px = np.array(msg.spots, dtype=np.float64).reshape(-1, 2)
            n = len(px)
            with self._lock:
                self.recent.append(SpotsObserved(upd.t_ns, px, np.ones(n), np.ones(n)))
        with self._lock:
            if msg.x is not None or withheld or msg.floor_unknown:
                self.latest = upd
                self.poses += 1
                if msg.mode == "landmark" and msg.x is not None:
                    self.last_fix_t_ns = upd.t_ns
            old, self._mode = self._mode, msg.mode
            self._remote.mode = msg.mode
        self._publish(upd)
        if old != msg.mode and self.on_mode_change is not None:
            self.on_mode_change(self.name, old, msg.mode)
        return upd

    # -- what differs from a robot localized here -------------------------------------------------
    def post(self, event: Event) -> None:
        """LED states reach the agent over MQTT (`<site>/leds`), not through the runner."""

    def handle(self, event: Event) -> None:
        """Sensor events are the agent's; nothing is localized here."""

    def relocalize(self, t_ns: int, near: tuple[float, float, float] | None = None) -> None:
        self._send_command(self.name, near)

    def set_map(self, landmark_map: LandmarkMap, map_version: int | None = None) -> None:
        """The map reaches the agent over MQTT (`<site>/map`, retained)."""
        if map_version is not None:
            self.map_version = map_version

    def start_recording(self, root: Any, landmark_records: list[dict[str, Any]]) -> None:
        raise ValueError(
            f"robot {self.name!r} is localized on the robot (source 'agent'): its frames "
            "stay there; record on the robot"
        )


def agent_fields(runner: AgentRunner) -> dict[str, Any]:
    """What `GET /robots` adds for an agent: connected, clock offset and error (s), and
    whether the offset is within what identification tolerates."""
    est = runner.clock
    return {
        "connected": runner.connected,
        "clock_offset_s": None if est is None else est.offset_ns / 1e9,
        "clock_error_s": None if est is None else est.error_ns / 1e9,
        "clock_ok": runner.clock_within_tolerance,
    }

"""The agents on the broker as robots of the site: an agent's arrival (`connection` ONLINE
and a status) registers its robot (source `agent`) or marks it connected again, its loss
(OFFLINE, or its last will CONNECTIONBROKEN) marks it disconnected; each is a site event.
Its status is checked against the site (the map version it holds, the floor it is on, its
clock's offset) and its LED requests go to the coordinator when the guard serves them.

No MQTT here: the bridge (`live.mqtt_bridge`) decodes the messages and hands them over, and
sends what this asks for through the callables it gives.
"""

from __future__ import annotations

import functools
import json
import logging
from collections.abc import Callable
from typing import TYPE_CHECKING

from fleet.clock import ClockConfig
from fleet.payloads import AgentStatus, LedRequestMessage, PayloadError, PoseMessage
from live.agent_floors import AgentFloors, Message
from live.agent_runner import AgentRunner
from live.events import EmitEvent
from live.fleet_guard import FleetGuard
from live.pose_reasons import ReasonTally, mode_change_event
from localizer.events import Mode

if TYPE_CHECKING:
    from live.services import SiteServices

log = logging.getLogger(__name__)


class FleetAgents:
    """The site's side of each agent.

    Args:
        services: the started site.
        guard: which agents are admitted and served.
        agent_floors: each agent's floor and its floor's map.
        clock: the clock tolerance that warnings are given against.
        emit: writes a site event.
        send_all: publishes retained messages (maps, floor assignments).
        send_default_map: publishes the default floor's map on the legacy `map` topic.
        send_command: tells an agent to relocalize (near a pose, or anywhere).
        site_from_wall: a time of this server's wall clock on the site clock.
    """

    def __init__(
        self,
        services: SiteServices,
        guard: FleetGuard,
        agent_floors: AgentFloors,
        clock: ClockConfig,
        *,
        emit: EmitEvent,
        send_all: Callable[[list[Message]], None],
        send_default_map: Callable[[], None],
        send_command: Callable[[str, tuple[float, float, float] | None], None],
        site_from_wall: Callable[[int], int],
    ) -> None:
        self.services = services
        self.guard = guard
        self.agent_floors = agent_floors
        self.clock = clock
        self._emit = emit
        self._send_all = send_all
        self._send_default_map = send_default_map
        self._send_command = send_command
        self._site_from_wall = site_from_wall
        self._status: dict[str, AgentStatus] = {}
        self._outdated_told: dict[str, int] = {}  # agent -> the old version it was told of
        self._online: set[str] = set()

    def agent(self, robot: str) -> AgentRunner | None:
        """The runner of an agent's robot (None: no robot of that name, or not an agent's)."""
        try:
            runner = self.services.robots.get(robot)
        except KeyError:
            return None
        return runner if isinstance(runner, AgentRunner) else None

    def on_pose(self, robot: str, msg: PoseMessage) -> None:
        """A registered agent's pose inside the site goes onto the pose bus."""
        runner = self.agent(robot)
        if runner is not None and self.guard.inside_site(robot, msg):
            runner.receive(msg)

    def on_connection(self, robot: str, payload: bytes) -> None:
        """A VDA 5050 `connection` message of an agent."""
        try:
            state = json.loads(payload).get("connectionState")
        except (json.JSONDecodeError, AttributeError):
            raise PayloadError(f"connection of {robot}: not a JSON object") from None
        runner = self.agent(robot)
        if state == "ONLINE":
            self._online.add(robot)
            if robot in self._status:
                self._arrive(robot, self._status[robot])
        elif state in ("OFFLINE", "CONNECTIONBROKEN"):
            self._online.discard(robot)
            if runner is not None and runner.connected:
                runner.connected = False
                how = "went offline" if state == "OFFLINE" else "lost (connection broken)"
                self._emit(
                    "robot_disconnected",
                    f"agent {robot} {how}; its pose is no longer updated",
                    robot=robot,
                    data={"source": "agent", "state": state},
                )
        else:
            raise PayloadError(f"connection of {robot}: connectionState {state!r}")

    def on_status(self, robot: str, status: AgentStatus) -> None:
        """An agent's status: kept, checked, and its robot registered once it is online."""
        self._status[robot] = status
        self._check_map_version(robot, status)
        runner = self.agent(robot)
        if runner is None:
            if robot in self._online:
                self._arrive(robot, status)
            return
        was_ok = runner.clock_within_tolerance
        runner.update_status(status)
        self._check_clock(runner, was_ok)

    def on_led_request(self, robot: str, msg: LedRequestMessage) -> None:
        """An admitted, connected agent's LED request goes to the coordinator; others are
        ignored (a phantom agent must not darken the ceiling)."""
        coordinator = self.services.leds.coordinator
        runner = self.agent(robot)
        if coordinator is None or runner is None or not runner.connected:
            return
        if self.guard.serves_led_requests(robot):
            coordinator.request(robot, msg.request())

    def _check_map_version(self, robot: str, status: AgentStatus) -> None:
        """An agent holding an old version of its floor's map is told: an event
        `agent_map_outdated` (once per version it holds) and the map published again; one
        on another floor than the site has it on is told its floor again."""
        runner = self.agent(robot)
        floor = runner.floor if runner is not None else self.services.floors.default()
        if runner is not None and status.floor is not None and status.floor != floor:
            told = self.agent_floors.assigned(robot)
            self._send_all([told] if told is not None else [])
            return
        held = status.map_version
        if held is None:
            return
        current = self.services.map_versions.version(floor)
        if held >= current or self._outdated_told.get(robot) == held:
            return
        self._outdated_told[robot] = held
        self._emit(
            "agent_map_outdated",
            f"agent {robot} localizes on version {held} of floor {floor}'s map; the current "
            f"one is {current}: published again",
            robot=robot,
            data={"floor": floor, "held": held, "current": current},
        )
        self._send_all([self.agent_floors.floor_map(floor)])
        if floor == self.services.floors.default():
            self._send_default_map()

    def _arrive(self, robot: str, status: AgentStatus) -> None:
        """Register (or mark connected again) an agent's robot; an event either way."""
        runner = self.agent(robot)
        if runner is None:
            if robot in self.services.robots.names():
                log.error("agent %s: a robot of that name is localized here; ignored", robot)
                return
            agents = sum(1 for r in self.services.robots.runners() if isinstance(r, AgentRunner))
            refusal = self.guard.refusal(robot, agents)
            if refusal is not None:
                self.guard.refuse(robot, refusal)
                return
            runner = AgentRunner(
                robot,
                status,
                publish=self.services.poses.publish,
                send_command=self._send_command,
                site_from_wall=self._site_from_wall,
            )
            runner.on_mode_change = functools.partial(self._on_mode_change, runner.reasons)
            floor = self.agent_floors.start_floor(status, robot)
            runner.floor = floor
            runner.map_version = self.services.map_versions.version(floor)
            self.services.robots.add(runner)
            self._send_all([self.agent_floors.assign(robot, floor)])
        elif runner.connected:
            return
        runner.connected = True
        runner.update_status(status)
        self._emit(
            "robot_connected",
            f"agent {robot} connected ({status.source})",
            robot=robot,
            data={"source": "agent"},
        )
        self._check_clock(runner, None)

    def _check_clock(self, runner: AgentRunner, was_ok: bool | None) -> None:
        est = runner.clock
        if est is None:
            return
        ok = est.within(self.clock.tolerance_s)
        runner.clock_within_tolerance = ok
        if not ok and was_ok is not False:
            self._emit(
                "clock_offset",
                f"agent {runner.name}: clock off by {est.offset_ns / 1e6:+.1f} ms "
                f"(+- {est.error_ns / 1e6:.1f} ms), more than identification tolerates "
                f"({self.clock.tolerance_s * 1e3:.0f} ms): LED times are corrected, but "
                "synchronise its clock (chrony)",
                robot=runner.name,
                data={"offset_ns": est.offset_ns, "error_ns": est.error_ns},
            )

    def _on_mode_change(self, reasons: ReasonTally, robot: str, old: Mode, new: Mode) -> None:
        event = mode_change_event(robot, old, new, reasons)
        if event is not None:
            kind, message, data = event
            self._emit(kind, message, robot=robot, data=data or None)

"""The site server on MQTT (`irloc serve --mqtt mqtt://HOST:PORT`): publishes the map and
every LED state, serves the agents' LED requests through the one RF gateway, answers their
clock exchanges, and brings their poses onto the pose bus as robots with source `agent`.
An agent's arrival (`connection` ONLINE) and loss (OFFLINE, or its last will
CONNECTIONBROKEN) are site events. Topics and payloads: `fleet`, docs/fleet.md.

What a hostile or broken client on the broker could do is bounded here too (the broker's
ACL is the lock, docs/fleet.md): only admitted agents (names or patterns in `mqtt_agents`,
else any up to `mqtt_max_agents`) are registered; their LED requests are served when they
are admitted by name, or when the server logs in to the broker (its ACL then vouches for
who wrote what), never on an open broker without a list; poses outside the
site are dropped and counted; a map on the map topic that this server did not publish is
replaced by the site's at once. Each is a `fleet_intrusion` event.

Runs on the server's event loop. When the broker goes away it reconnects by itself
(backoff 0.2-2 s) and publishes the map and the current LED state again (retained), so a
broker restarted without persistence is whole again; agents' robots stay registered.
"""

from __future__ import annotations

import asyncio
import contextlib
import fnmatch
import functools
import hashlib
import json
import logging
import math
import time
from collections import deque
from concurrent.futures import ThreadPoolExecutor
from typing import TYPE_CHECKING, Any

import aiomqtt

from fleet.broker import BrokerAddress
from fleet.clock import ClockConfig
from fleet.payloads import (
    AgentStatus,
    ClockReply,
    ClockRequest,
    CommandMessage,
    LedRequestMessage,
    LedStateMessage,
    MapLandmark,
    MapMessage,
    PayloadError,
    PoseMessage,
    ServerState,
    decode,
)
from fleet.session import run_session, until_first_ends
from fleet.topics import (
    QOS_CLOCK,
    QOS_STATE,
    SiteTopics,
    vda_connection_wildcard,
    vda_serial_of,
)
from live.agent_runner import AgentRunner
from live.events import EventKind
from live.pose_reasons import ReasonTally, mode_change_event
from localizer.events import LedsChanged, Mode
from store.models import LandmarkPublic

if TYPE_CHECKING:
    from live.services import SiteServices

log = logging.getLogger(__name__)
SITE_MARGIN_M = 50.0
"""Poses farther than this outside the map's extent are dropped."""
MAX_ABS_XY_M = 10_000.0
MAX_PENDING = 1000
"""Messages handed to the connection and not yet written before the bridge waits."""


class MqttBridge:
    """Connect a running site to the broker.

    Args:
        services: the started site.
        broker: where the broker is.
        site: the site name in the topics.
        manufacturer: VDA 5050 manufacturer of the agents listened to.
        clock: the clock tolerance that warnings are given against.
    """

    def __init__(
        self,
        services: SiteServices,
        broker: BrokerAddress,
        *,
        site: str,
        manufacturer: str = "irloc",
        clock: ClockConfig | None = None,
    ) -> None:
        self.services = services
        self.broker = broker
        self.topics = SiteTopics(site)
        self.manufacturer = manufacturer
        self.clock = clock or ClockConfig()
        self.client: aiomqtt.Client | None = None
        self.connects = 0
        self.received = 0
        self.received_bytes = 0
        self.rejected = 0
        self._loop = asyncio.get_running_loop()
        self._out: asyncio.Queue[tuple[str, bytes, int, bool]] = asyncio.Queue()
        self._task: asyncio.Task[None] | None = None
        self._led_seq = 0
        self._led_last: bytes | None = None
        self._status: dict[str, AgentStatus] = {}
        self._outdated_told: dict[str, int] = {}  # agent -> the old version it was told of
        self._online: set[str] = set()
        self._gateway_listening = False
        self._events = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mqtt-events")
        s = services.settings
        self.admitted = tuple(s.mqtt_agents)
        self.trust_logins = broker.username is not None
        self.led_requests_refused = 0
        self._led_refusal_told: set[str] = set()
        self.max_agents = s.mqtt_max_agents
        self.foreign_maps = 0
        self.poses_outside = 0
        self.refused_agents: set[str] = set()
        self._maps_sent: deque[bytes] = deque(maxlen=8)
        self._outside_told: set[str] = set()
        self._bounds = _extent(services.map.list())

    # -- lifecycle --------------------------------------------------------------------------------
    def start(self) -> None:
        self.services.map.add_listener(self._on_map)
        self._gateway_listening = self.services.leds.add_listener(self._on_leds)
        self._task = self._loop.create_task(self._run())

    async def stop(self) -> None:
        self.services.map.remove_listener(self._on_map)
        if self._gateway_listening:
            self.services.leds.remove_listener(self._on_leds)
        client = self.client
        if client is not None:
            with contextlib.suppress(aiomqtt.MqttError):
                await client.publish(
                    self.topics.server, ServerState(state="OFFLINE").encode(), qos=1, retain=True
                )
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._task
        await asyncio.to_thread(self._events.shutdown, wait=True)

    # -- clocks ---------------------------------------------------------------------------------
    def _wall_minus_site(self) -> int:
        return time.time_ns() - self.services.clock_ns()

    def site_from_wall(self, wall_ns: int) -> int:
        """A time of this server's wall clock (what the wire carries) on the site clock."""
        return wall_ns - self._wall_minus_site()

    # -- outgoing ------------------------------------------------------------------------------
    def _send(self, topic: str, payload: bytes, qos: int, retain: bool = False) -> None:
        """Queue a message from any thread (sent while connected, dropped otherwise)."""
        self._loop.call_soon_threadsafe(self._out.put_nowait, (topic, payload, qos, retain))

    def map_message(self, landmarks: list[LandmarkPublic] | None = None) -> bytes:
        """The map the agents localize on: the agents' floor (the site's default floor)
        with its version."""
        floor = self.services.floors.default()
        items = landmarks if landmarks is not None else self.services.map.list()
        lms = [MapLandmark(id=lm.id, x=lm.x, y=lm.y, z=lm.z) for lm in items if lm.floor == floor]
        body = json.dumps([lm.model_dump() for lm in lms], sort_keys=True).encode()
        map_id = f"{self.topics.site}-{hashlib.sha256(body).hexdigest()[:12]}"
        version = self.services.map_versions.version(floor)
        return MapMessage(map_id=map_id, landmarks=lms, floor=floor, version=version).encode()

    def _map_now(self, landmarks: list[LandmarkPublic] | None = None) -> bytes:
        """The map message to publish now, remembered as ours (`_on_foreign_map`)."""
        msg = self.map_message(landmarks)
        self._maps_sent.append(msg)
        return msg

    def _on_map(self, landmarks: list[LandmarkPublic]) -> None:
        self._bounds = _extent(landmarks)
        self._send(self.topics.map, self._map_now(landmarks), QOS_STATE, True)

    def _on_map_seen(self, payload: bytes) -> None:
        """A map on the map topic: ours comes back; any other was written by someone else
        (a broker without irloc's ACL): publish ours again, with an event."""
        if payload in self._maps_sent or not payload:
            return
        self.foreign_maps += 1
        self._send(self.topics.map, self._map_now(), QOS_STATE, True)
        if self.foreign_maps == 1 or self.foreign_maps % 100 == 0:
            self._emit(
                "fleet_intrusion",
                f"a map not published by this server appeared on {self.topics.map} "
                f"({self.foreign_maps} so far): the site's map was published again; "
                "restrict the broker with irloc's ACL (docs/fleet.md)",
                robot=None,
                data={"what": "foreign_map", "count": self.foreign_maps},
            )

    def _on_leds(self, event: LedsChanged) -> None:
        """Every LED state, as the gateway publishes it (before the LEDs switch)."""
        wall = event.t_ns + self._wall_minus_site()
        msg = LedStateMessage.from_event(self._led_seq, event, wall).encode()
        self._led_seq += 1
        self._led_last = msg
        self._send(self.topics.leds, msg, QOS_STATE, True)

    def _send_command(self, robot: str, near: tuple[float, float, float] | None) -> None:
        msg = CommandMessage(command="relocalize", near=near)
        self._send(self.topics.command(robot), msg.encode(), QOS_STATE)

    async def _sender(self, client: aiomqtt.Client) -> None:
        """Hand each message to the connection in order without waiting for the one before
        (paho queues them; awaiting each would hold every clock reply behind one write)."""
        pending: set[asyncio.Task[None]] = set()
        while True:
            topic, payload, qos, retain = await self._out.get()
            task = asyncio.create_task(client.publish(topic, payload, qos=qos, retain=retain))
            pending.add(task)
            task.add_done_callback(pending.discard)
            task.add_done_callback(_count_failure)
            if len(pending) > MAX_PENDING:
                await asyncio.wait(pending, return_when=asyncio.FIRST_COMPLETED)

    # -- the connection -------------------------------------------------------------------------
    async def _run(self) -> None:
        offline = ServerState(state="OFFLINE").encode()

        async def serve(client: aiomqtt.Client) -> bool:
            try:
                await self._online_now(client)
                await until_first_ends(self._receive(client), self._sender(client))
            except aiomqtt.MqttError:
                pass
            self.client = None
            return False

        await run_session(
            self.broker,
            identifier=f"irloc-server-{self.topics.site}",
            will=lambda: aiomqtt.Will(self.topics.server, offline, qos=1, retain=True),
            serve=serve,
            stop=asyncio.Event(),  # runs until the bridge's task is cancelled
            name="site server",
        )

    async def _online_now(self, client: aiomqtt.Client) -> None:
        t = self.topics
        # what queued while away is stale: the current map and LED state replace it
        while not self._out.empty():
            self._out.get_nowait()
        await client.subscribe(
            [
                (t.agents_wildcard, QOS_STATE),
                (t.clock_request, QOS_CLOCK),
                (t.map, QOS_STATE),
                (vda_connection_wildcard(self.manufacturer), QOS_STATE),
            ]
        )
        await client.publish(t.map, self._map_now(), qos=QOS_STATE, retain=True)
        if self._led_last is not None:
            await client.publish(t.leds, self._led_last, qos=QOS_STATE, retain=True)
        await client.publish(t.server, ServerState(state="ONLINE").encode(), qos=1, retain=True)
        self.connects += 1
        self.client = client
        log.info("broker %s: connected (site %s)", self.broker, t.site)

    async def _receive(self, client: aiomqtt.Client) -> None:
        async for message in client.messages:
            t2 = time.time_ns()
            topic = message.topic.value
            payload = message.payload
            if not isinstance(payload, bytes | bytearray):
                continue
            self.received += 1
            self.received_bytes += len(payload) + len(topic)
            try:
                self._dispatch(client, topic, bytes(payload), t2, bool(message.retain))
            except (PayloadError, ValueError) as exc:
                self.rejected += 1
                log.warning("ignored a message on %s: %s", topic, exc)

    def _dispatch(
        self, client: aiomqtt.Client, topic: str, payload: bytes, t2: int, retained: bool
    ) -> None:
        t = self.topics
        if topic == t.clock_request:
            req = decode(ClockRequest, topic, payload)
            reply = ClockReply(n=req.n, t1=req.t1, t2=t2, t3=time.time_ns())
            self._out.put_nowait((t.clock_reply(req.robot), reply.encode(), QOS_CLOCK, False))
            return
        if topic == t.map:
            self._on_map_seen(payload)
            return
        serial = vda_serial_of(topic)
        if serial is not None and topic.endswith("/connection"):
            self._on_connection(serial, payload, retained)
            return
        parts = t.agent_of(topic)
        if parts is None:
            return
        robot, leaf = parts
        if leaf == "pose":
            runner = self._agent(robot)
            if runner is not None:
                msg = decode(PoseMessage, topic, payload)
                if self._inside_site(robot, msg):
                    runner.receive(msg)
        elif leaf == "status":
            if payload:
                self._on_status(robot, decode(AgentStatus, topic, payload))
        elif leaf == "led_request":
            self._on_led_request(robot, decode(LedRequestMessage, topic, payload))

    def _emit(
        self,
        kind: EventKind,
        message: str,
        *,
        robot: str | None,
        data: dict[str, Any] | None = None,
    ) -> None:
        """A site event, written off the loop (each is a database commit: a hundred agents
        arriving at once must not stall the pose stream)."""
        emit = functools.partial(self.services.events.emit, robot=robot, data=data)
        self._loop.run_in_executor(self._events, emit, kind, message)

    # -- agents ---------------------------------------------------------------------------------
    def _agent(self, robot: str) -> AgentRunner | None:
        try:
            runner = self.services.robots.get(robot)
        except KeyError:
            return None
        return runner if isinstance(runner, AgentRunner) else None

    def _on_connection(self, robot: str, payload: bytes, retained: bool) -> None:
        try:
            state = json.loads(payload).get("connectionState")
        except (json.JSONDecodeError, AttributeError):
            raise PayloadError(f"connection of {robot}: not a JSON object") from None
        emit = self._emit
        runner = self._agent(robot)
        if state == "ONLINE":
            self._online.add(robot)
            if robot in self._status:
                self._arrive(robot, self._status[robot])
        elif state in ("OFFLINE", "CONNECTIONBROKEN"):
            self._online.discard(robot)
            if runner is not None and runner.connected:
                runner.connected = False
                how = "went offline" if state == "OFFLINE" else "lost (connection broken)"
                emit(
                    "robot_disconnected",
                    f"agent {robot} {how}; its pose is no longer updated",
                    robot=robot,
                    data={"source": "agent", "state": state},
                )
        else:
            raise PayloadError(f"connection of {robot}: connectionState {state!r}")

    def _on_status(self, robot: str, status: AgentStatus) -> None:
        self._status[robot] = status
        self._check_map_version(robot, status)
        runner = self._agent(robot)
        if runner is None:
            if robot in self._online:
                self._arrive(robot, status)
            return
        was_ok = runner.clock_within_tolerance
        runner.update_status(status)
        self._check_clock(runner, was_ok)

    def _check_map_version(self, robot: str, status: AgentStatus) -> None:
        """An agent holding an old version of its floor's map is told: an event
        `agent_map_outdated` (once per version it holds) and the map published again."""
        held = status.map_version
        if held is None:
            return
        floor = self.services.floors.default()
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
        self._send(self.topics.map, self.map_message(), QOS_STATE, True)

    def _arrive(self, robot: str, status: AgentStatus) -> None:
        """Register (or mark connected again) an agent's robot; an event either way."""
        runner = self._agent(robot)
        if runner is None:
            if robot in self.services.robots.names():
                log.error("agent %s: a robot of that name is localized here; ignored", robot)
                return
            refusal = self._refusal(robot)
            if refusal is not None:
                if robot not in self.refused_agents:
                    self.refused_agents.add(robot)
                    self._emit("fleet_intrusion", f"agent {robot} refused: {refusal}",
                               robot=robot, data={"what": "agent_refused"})  # fmt: skip
                return
            runner = AgentRunner(
                robot,
                status,
                publish=self.services.poses.publish,
                send_command=self._send_command,
                site_from_wall=self.site_from_wall,
            )
            runner.on_mode_change = functools.partial(self._on_mode_change, runner.reasons)
            self.services.robots.add(runner)
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

    def _admitted(self, robot: str) -> bool:
        return any(fnmatch.fnmatchcase(robot, pattern) for pattern in self.admitted)

    def _refusal(self, robot: str) -> str | None:
        """Why a new agent may not join (None: it may)."""
        if self.admitted and not self._admitted(robot):
            return "not among the admitted agents (setting mqtt_agents)"
        agents = sum(1 for r in self.services.robots.runners() if isinstance(r, AgentRunner))
        if agents >= self.max_agents:
            return f"the site has its {self.max_agents} agents (setting mqtt_max_agents)"
        return None

    def _inside_site(self, robot: str, msg: PoseMessage) -> bool:
        """Whether a pose is on the site (the map's extent and `SITE_MARGIN_M` around it);
        one outside is dropped and counted (an event the first time for each agent)."""
        if msg.x is None or msg.y is None:
            return True
        box = self._bounds
        if box is not None:
            x0, y0, x1, y1 = box
            m = SITE_MARGIN_M
            if (
                x0 - m <= msg.x <= x1 + m
                and y0 - m <= msg.y <= y1 + m
                and math.isfinite(msg.theta if msg.theta is not None else 0.0)
            ):
                return True
        elif abs(msg.x) <= MAX_ABS_XY_M and abs(msg.y) <= MAX_ABS_XY_M:
            return True
        self.poses_outside += 1
        if robot not in self._outside_told:
            self._outside_told.add(robot)
            self._emit(
                "fleet_intrusion",
                f"agent {robot}: a pose outside the site (x {msg.x:.4g}, y {msg.y:.4g} m) "
                "dropped; such poses are dropped and counted",
                robot=robot,
                data={"what": "pose_outside", "x": msg.x, "y": msg.y},
            )
        return False

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

    def _on_led_request(self, robot: str, msg: LedRequestMessage) -> None:
        """An admitted, connected agent's LED request goes to the coordinator; others are
        ignored (a phantom agent must not darken the ceiling)."""
        coordinator = self.services.leds.coordinator
        runner = self._agent(robot)
        if coordinator is None or runner is None or not runner.connected:
            return
        if not self.admitted and not self.trust_logins:
            # an open broker and no list: anyone could claim to be this agent
            self.led_requests_refused += 1
            if robot not in self._led_refusal_told:
                self._led_refusal_told.add(robot)
                self._emit(
                    "fleet_intrusion",
                    f"agent {robot}: its LED requests are not served: the broker is open (no "
                    "login) and no agent is admitted (setting mqtt_agents, docs/fleet.md)",
                    robot=robot,
                    data={"what": "led_request_refused"},
                )
            return
        coordinator.request(robot, msg.request())


def _extent(landmarks: list[LandmarkPublic]) -> tuple[float, float, float, float] | None:
    """(x min, y min, x max, y max) of the map, None when it is empty."""
    if not landmarks:
        return None
    xs, ys = [lm.x for lm in landmarks], [lm.y for lm in landmarks]
    return min(xs), min(ys), max(xs), max(ys)


def _count_failure(task: asyncio.Task[None]) -> None:
    """A publish that failed: the connection is going (the receive loop ends the session)."""
    if not task.cancelled() and task.exception() is not None:
        log.debug("publish failed: %s", task.exception())


async def start_mqtt_bridge(services: SiteServices) -> MqttBridge | None:
    """The bridge for `settings.mqtt_url`, started (None without one)."""
    s = services.settings
    if not s.mqtt_url:
        return None
    bridge = MqttBridge(services, s.broker(), site=s.mqtt_site, manufacturer=s.vda_manufacturer)
    bridge.start()
    return bridge

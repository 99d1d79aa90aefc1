"""The site server on MQTT (`irloc serve --mqtt mqtt://HOST:PORT`): publishes the map and
every LED state, serves the agents' LED requests through the one RF gateway, answers their
clock exchanges, and brings their poses onto the pose bus as robots with source `agent`.
An agent's arrival (`connection` ONLINE) and loss (OFFLINE, or its last will
CONNECTIONBROKEN) are site events. Topics and payloads: `fleet`, docs/fleet.md.

What a hostile or broken client on the broker could do is bounded here too (the broker's
ACL is the lock, docs/fleet.md): `FleetGuard` (`live.fleet_guard`) decides which agents are
registered, whose LED requests are served and which poses are dropped; a map on the map
topic that this server did not publish is replaced by the site's at once.

What an agent's messages mean for its robot on the site (arrival, loss, status checks,
LED requests) is `live.fleet_agents`; this module is the broker connection around it.

Each floor's map goes on its own retained topic and each agent is told its floor, again
when it changes floors (`live.agent_floors`); an agent's poses on another floor's map than
the site has it on are withheld.

Runs on the server's event loop. When the broker goes away it reconnects by itself
(backoff 0.2-2 s) and publishes the map and the current LED state again (retained), so a
broker restarted without persistence is whole again; agents' robots stay registered.
"""

from __future__ import annotations

import asyncio
import contextlib
import functools
import logging
import time
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
from live.agent_floors import AgentFloors, Message, Near
from live.alerts import Notification
from live.events import EventKind
from live.fleet_agents import FleetAgents
from live.fleet_guard import FleetGuard
from localizer.events import LedsChanged
from store.models import LandmarkPublic

if TYPE_CHECKING:
    from live.services import SiteServices

log = logging.getLogger(__name__)
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
        self._gateway_listening = False
        self._events = ThreadPoolExecutor(max_workers=1, thread_name_prefix="mqtt-events")
        self.guard = FleetGuard(
            admitted=tuple(services.settings.mqtt_agents),
            max_agents=services.settings.mqtt_max_agents,
            trust_logins=broker.username is not None,
            landmarks=services.map.list(),
            emit=self._emit,
        )
        self._alerts: dict[str, bytes] = {}  # topic -> retained payload of each active alert
        self.agent_floors = AgentFloors(services, self.topics)
        self.agents = FleetAgents(
            services,
            self.guard,
            self.agent_floors,
            self.clock,
            emit=self._emit,
            send_all=self._send_all,
            send_default_map=self._send_default_map,
            send_command=self._send_command,
            site_from_wall=self.site_from_wall,
        )

    # -- lifecycle --------------------------------------------------------------------------------
    def start(self) -> None:
        self.services.map.add_listener(self._on_map)
        self.services.site_floors.add_listener(self._on_moved)
        self._gateway_listening = self.services.leds.add_listener(self._on_leds)
        self.services.alerts.add_listener(self._on_alert)
        self._task = self._loop.create_task(self._run())

    async def stop(self) -> None:
        self.services.map.remove_listener(self._on_map)
        self.services.alerts.remove_listener(self._on_alert)
        self.services.site_floors.remove_listener(self._on_moved)
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
        """The default floor's map with its version (the legacy `map` topic's)."""
        items = landmarks if landmarks is not None else self.services.map.list()
        return self.agent_floors.map_message(self.services.floors.default(), items)

    def _send_default_map(self) -> None:
        self._send(self.topics.map, self.map_message(), QOS_STATE, True)

    def _send_all(self, messages: list[Message]) -> None:
        for topic, payload in messages:
            self._send(topic, payload, QOS_STATE, True)

    def _on_map(self, landmarks: list[LandmarkPublic]) -> None:
        self.guard.set_map(landmarks)
        self._send_all(self.agent_floors.maps(landmarks, changed=True))

    def _on_moved(self, robot: str, floor: str, old: str, near: Near | None) -> None:
        """A robot changed floors (told, or a proposal accepted): an agent is told."""
        if self.agents.agent(robot) is not None:
            self._send_all([self.agent_floors.assign(robot, floor, near)])

    def _on_map_seen(self, topic: str, payload: bytes) -> None:
        """A map on a map topic: ours comes back; any other was written by someone else
        (a broker without irloc's ACL): publish ours again, with an event."""
        if self.agent_floors.is_ours(payload):
            return
        self._send_all(self.agent_floors.maps(changed=False))
        self.guard.foreign_map(topic)

    def _on_leds(self, event: LedsChanged) -> None:
        """Every LED state, as the gateway publishes it (before the LEDs switch)."""
        wall = event.t_ns + self._wall_minus_site()
        msg = LedStateMessage.from_event(self._led_seq, event, wall).encode()
        self._led_seq += 1
        self._led_last = msg
        self._send(self.topics.leds, msg, QOS_STATE, True)

    def _on_alert(self, note: Notification) -> None:
        """An alert raised: retained on its topic; resolved: the resolved message, then the
        retained one cleared (docs/alerts.md)."""
        c = note.alert.condition
        topic = self.topics.alert(c.kind, c.subject)
        payload = note.json(self.topics.site)
        if note.state == "raised":
            self._alerts[topic] = payload
            self._send(topic, payload, QOS_STATE, True)
        else:
            self._alerts.pop(topic, None)
            self._send(topic, payload, QOS_STATE, False)
            self._send(topic, b"", QOS_STATE, True)

    def _on_alert_seen(self, topic: str, payload: bytes, retained: bool) -> None:
        """A retained alert the broker kept from before (this server's last run): cleared
        when it is not active now."""
        if retained and payload and topic not in self._alerts:
            self._send(topic, b"", QOS_STATE, True)

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
                (t.alerts_wildcard, QOS_STATE),
                (t.floor_maps_wildcard, QOS_STATE),
                (vda_connection_wildcard(self.manufacturer), QOS_STATE),
            ]
        )
        messages = self.agent_floors.maps(changed=False) + self.agent_floors.assignments()
        for topic, payload in messages:
            await client.publish(topic, payload, qos=QOS_STATE, retain=True)
        if self._led_last is not None:
            await client.publish(t.leds, self._led_last, qos=QOS_STATE, retain=True)
        for topic, payload in list(self._alerts.items()):  # a broker restarted empty
            await client.publish(topic, payload, qos=QOS_STATE, retain=True)
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
        if topic == t.map or t.floor_of_map(topic) is not None:
            self._on_map_seen(topic, payload)
            return
        if t.is_alert(topic):
            self._on_alert_seen(topic, payload, retained)
            return
        serial = vda_serial_of(topic)
        if serial is not None and topic.endswith("/connection"):
            self.agents.on_connection(serial, payload)
            return
        parts = t.agent_of(topic)
        if parts is None:
            return
        robot, leaf = parts
        if leaf == "pose":
            if self.agents.agent(robot) is not None:
                self.agents.on_pose(robot, decode(PoseMessage, topic, payload))
        elif leaf == "status":
            if payload:
                self.agents.on_status(robot, decode(AgentStatus, topic, payload))
        elif leaf == "led_request":
            self.agents.on_led_request(robot, decode(LedRequestMessage, topic, payload))

    def _emit(
        self,
        kind: EventKind,
        message: str,
        *,
        robot: str | None = None,
        data: dict[str, Any] | None = None,
    ) -> None:
        """A site event, written off the loop (each is a database commit: a hundred agents
        arriving at once must not stall the pose stream)."""
        emit = functools.partial(self.services.events.emit, robot=robot, data=data)
        self._loop.run_in_executor(self._events, emit, kind, message)


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

"""The agent's network side: one MQTT connection per robot (aiomqtt), the sensor thread
that ticks every robot's `AgentCore`, the clock exchanges and the reconnect loop.

While the broker is away the robots go on localizing; their poses are dropped (a pose is
worth nothing later) and LED requests too (the localizer's identification asks again after
`led_timeout_s`). On every (re)connection the agent publishes `connection` ONLINE and its
status, and subscribes again: the retained maps (every floor's), its floor and the last LED
state bring it up to date.
"""

from __future__ import annotations

import asyncio
import contextlib
import itertools
import json
import logging
import threading
import time
from dataclasses import dataclass, field

import aiomqtt

from agent.core import AgentCore, Outgoing
from fleet.broker import BrokerAddress
from fleet.clock import ClockConfig, ClockFilter, ClockSample
from fleet.payloads import (
    ClockReply,
    ClockRequest,
    CommandMessage,
    FloorMessage,
    LedStateMessage,
    MapMessage,
    PayloadError,
    decode,
)
from fleet.session import BrokerUnreachableError, run_session, until_first_ends
from fleet.topics import QOS_CLOCK, QOS_POSE, QOS_STATE, SiteTopics, vda_topic
from fleet.vda5050 import ConnectionState, HeaderIds, connection_message

log = logging.getLogger(__name__)
TICK_S = 0.01
STATUS_INTERVAL_S = 5.0
MAX_INFLIGHT = 20
"""Batches of one robot handed to its connection and not yet written."""


@dataclass
class _Link:
    """One robot's connection state."""

    core: AgentCore
    clock: ClockFilter
    client: aiomqtt.Client | None = None
    connects: int = 0
    dropped: int = 0
    sent: int = 0
    sent_bytes: int = 0
    inflight: int = 0
    pending_clock: dict[int, int] = field(default_factory=dict)
    clock_n: int = 0


class AgentRuntime:
    """Run `cores` (one robot each) against the broker until `stop` is set.

    Args:
        broker: the site's broker.
        site: the site name in the topics.
        cores: the robots of this process.
        clock: clock exchange settings.
    """

    def __init__(
        self,
        broker: BrokerAddress,
        site: str,
        cores: list[AgentCore],
        clock: ClockConfig | None = None,
        first_connect_s: float | None = None,
    ) -> None:
        self.broker = broker
        self.first_connect_s = first_connect_s
        self.failed: str | None = None
        self.topics = SiteTopics(site)
        self.clock_config = clock or ClockConfig()
        self.links = [_Link(c, ClockFilter(self.clock_config)) for c in cores]
        self._headers = HeaderIds()
        self._loop: asyncio.AbstractEventLoop | None = None
        self._out: asyncio.Queue[tuple[_Link, list[Outgoing]]] = asyncio.Queue()
        self._thread_stop = threading.Event()

    async def run(self, stop: asyncio.Event) -> None:
        self._loop = asyncio.get_running_loop()
        worker = threading.Thread(target=self._sensor_loop, name="agent-sensors", daemon=True)
        worker.start()
        tasks = [asyncio.create_task(self._session(link, stop)) for link in self.links]
        tasks.append(asyncio.create_task(self._sender()))
        try:
            await stop.wait()
        finally:
            self._thread_stop.set()
            await asyncio.to_thread(worker.join, 5.0)
            for t in tasks:
                t.cancel()
            for t in tasks:
                with contextlib.suppress(asyncio.CancelledError, Exception):
                    await t

    # -- sensors (thread) --------------------------------------------------------------------
    def _sensor_loop(self) -> None:
        loop = self._loop
        assert loop is not None
        next_t = time.monotonic()
        while not self._thread_stop.is_set():
            now = time.monotonic_ns()
            for link in self.links:
                try:
                    outs = link.core.tick(now)
                except Exception:
                    log.exception("%s: sensor step failed", link.core.config.name)
                    continue
                if outs:
                    loop.call_soon_threadsafe(self._out.put_nowait, (link, outs))
            next_t += TICK_S
            delay = next_t - time.monotonic()
            if delay < 0:
                next_t = time.monotonic()
            else:
                self._thread_stop.wait(delay)

    async def _sender(self) -> None:
        """Hand each batch to its robot's connection without waiting for the one before
        (paho queues them in order; awaiting each publish would let one robot's socket
        delay every robot of the process). A robot with `MAX_INFLIGHT` batches unsent (its
        link stalled) drops the new ones: a late pose is worthless."""
        pending: set[asyncio.Task[None]] = set()
        while True:
            link, outs = await self._out.get()
            client = link.client
            if client is None or link.inflight >= MAX_INFLIGHT:
                link.dropped += len(outs)
                continue
            task = asyncio.create_task(self._publish(link, client, outs))
            pending.add(task)
            task.add_done_callback(pending.discard)

    async def _publish(self, link: _Link, client: aiomqtt.Client, outs: list[Outgoing]) -> None:
        name = link.core.config.name
        calls = []
        for o in outs:
            if o.kind == "pose":
                topic, qos = self.topics.pose(name), QOS_POSE
            elif o.kind == "led_request":
                topic, qos = self.topics.led_request(name), QOS_STATE
            else:
                topic = vda_topic(link.core.config.manufacturer, name, "visualization")
                qos = QOS_POSE
            calls.append(client.publish(topic, o.payload, qos=qos))
            link.sent_bytes += len(o.payload) + len(topic)
        link.inflight += 1
        try:
            results = await asyncio.gather(*calls, return_exceptions=True)
        finally:
            link.inflight -= 1
        failed = sum(isinstance(r, BaseException) for r in results)
        link.sent += len(results) - failed
        link.dropped += failed

    # -- one robot's connection ----------------------------------------------------------------
    def _connection(self, link: _Link, state: ConnectionState) -> bytes:
        cfg = link.core.config
        msg = connection_message(
            self._headers.take(cfg.name, "connection"),
            link.core.time.site_now_ns(),
            cfg.manufacturer,
            cfg.name,
            state,
        )
        return json.dumps(msg, separators=(",", ":")).encode()

    def _status(self, link: _Link) -> bytes:
        est = link.clock.estimate
        return link.core.status(
            None if est is None else est.offset_ns, None if est is None else est.error_ns
        ).encode()

    async def _session(self, link: _Link, stop: asyncio.Event) -> None:
        cfg = link.core.config
        conn_topic = vda_topic(cfg.manufacturer, cfg.name, "connection")

        def will() -> aiomqtt.Will:
            broken = self._connection(link, "CONNECTIONBROKEN")
            return aiomqtt.Will(conn_topic, broken, qos=1, retain=True)

        async def serve(client: aiomqtt.Client) -> bool:
            try:
                await self._online(link, client, conn_topic)
                await until_first_ends(
                    self._receive(link, client),
                    self._clock_loop(link, client),
                    self._status_loop(link, client),
                    stop.wait(),
                )
                link.client = None
                if stop.is_set():
                    offline = self._connection(link, "OFFLINE")
                    await client.publish(conn_topic, offline, qos=1, retain=True)
                    return True
            except aiomqtt.MqttError:
                pass
            link.client = None
            return False

        try:
            await run_session(
                self.broker,
                identifier=f"irloc-agent-{self.topics.site}-{cfg.name}",
                will=will,
                serve=serve,
                stop=stop,
                name=cfg.name,
                first_connect_s=self.first_connect_s,
            )
        except BrokerUnreachableError as exc:
            self.failed = str(exc)
            stop.set()
        link.client = None

    async def _online(self, link: _Link, client: aiomqtt.Client, conn_topic: str) -> None:
        name = link.core.config.name
        t = self.topics
        await client.subscribe(
            [
                (t.map, QOS_STATE),
                (t.floor_maps_wildcard, QOS_STATE),
                (t.floor_assignment(name), QOS_STATE),
                (t.leds, QOS_STATE),
                (t.command(name), QOS_STATE),
                (t.clock_reply(name), QOS_CLOCK),
            ]
        )
        await client.publish(conn_topic, self._connection(link, "ONLINE"), qos=1, retain=True)
        await client.publish(t.status(name), self._status(link), qos=1, retain=True)
        link.connects += 1
        link.client = client
        log.info("%s: connected to %s (connection %d)", name, self.broker, link.connects)

    async def _receive(self, link: _Link, client: aiomqtt.Client) -> None:
        t = self.topics
        core = link.core
        floor_topic = t.floor_assignment(core.config.name)
        async for message in client.messages:
            topic = message.topic.value
            payload = message.payload
            if not isinstance(payload, bytes | bytearray):
                continue
            try:
                if topic == t.leds:
                    core.on_leds(decode(LedStateMessage, topic, payload))
                elif topic == t.map or t.floor_of_map(topic) is not None:
                    core.on_map(decode(MapMessage, topic, payload))
                elif topic == floor_topic:
                    core.on_floor(decode(FloorMessage, topic, payload))
                elif topic.endswith("/clock/reply"):
                    self._clock_reply(link, decode(ClockReply, topic, payload))
                elif topic.endswith("/command"):
                    core.on_command(decode(CommandMessage, topic, payload))
            except (PayloadError, ValueError) as exc:
                log.warning("%s: ignored a message: %s", core.config.name, exc)

    async def _clock_loop(self, link: _Link, client: aiomqtt.Client) -> None:
        """A quick burst of exchanges after connecting, then one every `interval_s`."""
        name = link.core.config.name
        for i in itertools.count():
            link.clock_n += 1
            n = link.clock_n
            t1 = link.core.time.wall_ns()
            link.pending_clock = {k: v for k, v in link.pending_clock.items() if k > n - 8}
            link.pending_clock[n] = t1
            req = ClockRequest(robot=name, n=n, t1=t1)
            await client.publish(self.topics.clock_request, req.encode(), qos=QOS_CLOCK)
            await asyncio.sleep(0.1 if i < 4 else self.clock_config.interval_s)

    def _clock_reply(self, link: _Link, reply: ClockReply) -> None:
        t4 = link.core.time.wall_ns()
        if link.pending_clock.pop(reply.n, None) != reply.t1:
            return
        est = link.clock.add(ClockSample(reply.t1, reply.t2, reply.t3, t4))
        if est is not None:
            link.core.time.offset_ns = est.offset_ns

    async def _status_loop(self, link: _Link, client: aiomqtt.Client) -> None:
        while True:
            await asyncio.sleep(STATUS_INTERVAL_S if link.clock.estimate else 0.6)
            await client.publish(
                self.topics.status(link.core.config.name), self._status(link), qos=1, retain=True
            )

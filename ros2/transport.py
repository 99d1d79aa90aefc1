"""The one DDS transport: a participant on ROS 2's domain, publishers and subscriptions of
ROS 2 messages on ROS 2 topic names, with the QoS a ROS 2 graph expects.

`Ros2Participant(domain_id)` joins DDS domain `ROS_DOMAIN_ID` (default 0). With
`ROS_LOCALHOST_ONLY=1` (or ROS 2 Jazzy's `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`) it talks
only over the loopback interface, with unicast discovery to 127.0.0.1 (as ROS 2 does in that
mode); otherwise CycloneDDS's own configuration applies (`CYCLONEDDS_URI`, the same file a
robot's rmw_cyclonedds_cpp reads).

Every endpoint carries the ROS 2 type hash in its USER_DATA (`typehash=RIHS01_...;`, as
rmw_cyclonedds_cpp writes it since Iron), so ROS 2 tools see a well-formed endpoint.
"""

from __future__ import annotations

import contextlib
import logging
import os
import threading
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, Literal

from cyclonedds.core import (
    DDSException,
    InstanceState,
    ReadCondition,
    SampleState,
    ViewState,
    WaitSet,
)
from cyclonedds.domain import Domain, DomainParticipant
from cyclonedds.internal import InvalidSample
from cyclonedds.pub import DataWriter
from cyclonedds.qos import Policy, Qos
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic

from ros2.idl import dds_topic_name, message_class, typestore

log = logging.getLogger(__name__)

Reliability = Literal["reliable", "best_effort"]
Durability = Literal["volatile", "transient_local"]


@dataclass(frozen=True)
class QosProfile:
    """A ROS 2 QoS profile (history keep-last `depth`).

    The ones ROS 2 users know: `QOS_DEFAULT` (reliable, volatile, 10),
    `QOS_SENSOR_DATA` (best effort, volatile, 5: a reliable reader does not match a
    best-effort camera driver, a best-effort reader matches both), `QOS_LATCHED`
    (reliable, transient local, 1: a late subscriber gets the last message, as `/map` and
    `/tf_static`).
    """

    reliability: Reliability = "reliable"
    durability: Durability = "volatile"
    depth: int = 10

    def __post_init__(self) -> None:
        if self.reliability not in ("reliable", "best_effort"):
            raise ValueError(
                f"QoS reliability must be reliable or best_effort, got {self.reliability!r}"
            )
        if self.durability not in ("volatile", "transient_local"):
            raise ValueError(
                f"QoS durability must be volatile or transient_local, got {self.durability!r}"
            )
        if not 1 <= self.depth <= 10_000:
            raise ValueError(f"QoS depth must be in [1, 10000], got {self.depth}")

    def dds(self, ros_type: str) -> Qos:
        """The cyclonedds QoS of an endpoint of `ros_type` with this profile."""
        reliability = (
            Policy.Reliability.Reliable(max_blocking_time=100_000_000)
            if self.reliability == "reliable"
            else Policy.Reliability.BestEffort
        )
        durability = (
            Policy.Durability.TransientLocal
            if self.durability == "transient_local"
            else Policy.Durability.Volatile
        )
        typehash = f"typehash={typestore().hash_rihs01(ros_type)};".encode()
        return Qos(
            reliability,
            durability,
            Policy.History.KeepLast(depth=self.depth),
            Policy.Userdata(data=typehash),
        )


QOS_DEFAULT = QosProfile()
QOS_SENSOR_DATA = QosProfile("best_effort", "volatile", 5)
QOS_LATCHED = QosProfile("reliable", "transient_local", 1)


def domain_id_from_env(env: dict[str, str] | None = None) -> int:
    """`ROS_DOMAIN_ID` (0 when unset).

    Raises:
        ValueError: not an integer in [0, 232] (DDS's usable domain ids).
    """
    raw = (os.environ if env is None else env).get("ROS_DOMAIN_ID", "").strip()
    if not raw:
        return 0
    try:
        value = int(raw)
    except ValueError:
        raise ValueError(f"ROS_DOMAIN_ID must be an integer, got {raw!r}") from None
    if not 0 <= value <= 232:
        raise ValueError(f"ROS_DOMAIN_ID must be in [0, 232], got {value}")
    return value


def localhost_only_from_env(env: dict[str, str] | None = None) -> bool:
    """ROS 2's localhost-only switch: `ROS_LOCALHOST_ONLY=1` or
    `ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST`."""
    e = os.environ if env is None else env
    return (
        e.get("ROS_LOCALHOST_ONLY", "") == "1"
        or e.get("ROS_AUTOMATIC_DISCOVERY_RANGE", "").upper() == "LOCALHOST"
    )


LOOPBACK_CONFIG = """<CycloneDDS><Domain id="any"><General>
<Interfaces><NetworkInterface name="lo"/></Interfaces><AllowMulticast>false</AllowMulticast>
</General><Discovery><ParticipantIndex>auto</ParticipantIndex>
<MaxAutoParticipantIndex>60</MaxAutoParticipantIndex>
<Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>"""
"""CycloneDDS on the loopback interface only, unicast discovery (no multicast)."""


class Ros2Publisher:
    """A DDS writer of ROS 2 message `ros_type` on a ROS topic."""

    def __init__(self, writer: DataWriter[Any], topic: str, ros_type: str) -> None:
        self._writer = writer
        self.topic = topic
        self.ros_type = ros_type
        self.cls = message_class(ros_type)
        self.sent = 0

    def publish(self, message: Any) -> None:
        self._writer.write(message)
        self.sent += 1


class Ros2Subscription:
    """A DDS reader whose samples go to `callback(message)` on the participant's reader
    thread; an exception in the callback is logged and counted (`errors`)."""

    def __init__(self, topic: str, ros_type: str, callback: Callable[[Any], None]) -> None:
        self.topic = topic
        self.ros_type = ros_type
        self.callback = callback
        self.received = 0
        self.errors = 0
        self.reader: DataReader[Any] | None = None

    def drain(self) -> None:
        """Hand every sample waiting in the reader to the callback."""
        if self.reader is None:
            return
        for sample in self.reader.take(N=256):
            if isinstance(sample, InvalidSample):
                continue  # a writer left (dispose/unregister): no data
            self.received += 1
            try:
                self.callback(sample)
            except Exception:
                self.errors += 1
                log.exception("ROS 2 subscription %s: callback failed", self.topic)


class Ros2Participant:
    """One DDS participant on ROS 2's domain.

    Args:
        domain_id: DDS domain (None: `ROS_DOMAIN_ID`, default 0).
        localhost_only: loopback only (None: from `ROS_LOCALHOST_ONLY` /
            `ROS_AUTOMATIC_DISCOVERY_RANGE`).
    """

    def __init__(self, domain_id: int | None = None, *, localhost_only: bool | None = None) -> None:
        self.domain_id = domain_id_from_env() if domain_id is None else domain_id
        local = localhost_only_from_env() if localhost_only is None else localhost_only
        self._domain: Domain | None = None
        if local:
            # DDSException: this process is on the domain already (its first participant's config)
            with contextlib.suppress(DDSException):
                self._domain = Domain(self.domain_id, LOOPBACK_CONFIG)
        self.participant = DomainParticipant(self.domain_id)
        self._topics: dict[str, Topic[Any]] = {}
        self._lock = threading.Lock()
        self.subscriptions: list[Ros2Subscription] = []
        self._waitset = WaitSet(self.participant)
        self._conditions: list[ReadCondition] = []
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None

    def _topic(self, topic: str, ros_type: str) -> Topic[Any]:
        name = dds_topic_name(topic)
        with self._lock:
            t = self._topics.get(name)
            if t is None:
                t = Topic(self.participant, name, message_class(ros_type))
                self._topics[name] = t
            elif t.data_type is not message_class(ros_type):
                raise ValueError(f"ROS topic {topic} is already used with another type")
            return t

    def publisher(self, topic: str, ros_type: str, qos: QosProfile = QOS_DEFAULT) -> Ros2Publisher:
        writer: DataWriter[Any] = DataWriter(
            self.participant, self._topic(topic, ros_type), qos=qos.dds(ros_type)
        )
        return Ros2Publisher(writer, topic, ros_type)

    def subscribe(
        self,
        topic: str,
        ros_type: str,
        callback: Callable[[Any], None],
        qos: QosProfile = QOS_DEFAULT,
    ) -> Ros2Subscription:
        sub = Ros2Subscription(topic, ros_type, callback)
        sub.reader = DataReader(
            self.participant, self._topic(topic, ros_type), qos=qos.dds(ros_type)
        )
        condition = ReadCondition(
            sub.reader, SampleState.NotRead | ViewState.Any | InstanceState.Any
        )
        with self._lock:
            self._conditions.append(condition)
            self._waitset.attach(condition)
            self.subscriptions = [*self.subscriptions, sub]
            if self._thread is None:
                self._thread = threading.Thread(
                    target=self._read_loop, name="ros2-read", daemon=True
                )
                self._thread.start()
        return sub

    def _read_loop(self) -> None:
        """Wait for data on any reader, hand it over (CycloneDDS's listeners call Python from
        inside a local write; a reader thread keeps the middleware and the GIL apart)."""
        while not self._stop.is_set():
            self._waitset.wait(100_000_000)
            for sub in self.subscriptions:
                sub.drain()

    def close(self) -> None:
        """Stop reading and leave the domain."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout=2)
        self.participant.__del__()

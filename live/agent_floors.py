"""Floors for robot agents over MQTT: every floor's map on its own retained topic
(`<site>/maps/<floor>`, with its version), and each agent's floor on its own
(`agents/<robot>/floor`, `FloorMessage`): the floor whose map it must localize on, renewed
when it changes floors (told through the API or a VDA 5050 action, or a floor proposal
accepted), with the lift's node to identify near. The legacy `<site>/map` topic keeps
the default floor's map for agents that know no floors.

What to send is decided here; the MQTT bridge (`live.mqtt_bridge`) sends it.
"""

from __future__ import annotations

import hashlib
import json
import time
from collections import deque
from typing import TYPE_CHECKING

from fleet.payloads import AgentStatus, FloorMessage, MapLandmark, MapMessage
from fleet.topics import SiteTopics
from store.models import LandmarkPublic

if TYPE_CHECKING:
    from live.services import SiteServices

Near = tuple[float, float, float]
Message = tuple[str, bytes]
"""(topic, payload) of a retained message to publish."""


class AgentFloors:
    """The floor maps and the agents' floors (see the module docstring).

    Args:
        services: the running site (its floors, map and map versions).
        topics: the site's topics.
    """

    def __init__(self, services: SiteServices, topics: SiteTopics) -> None:
        self.services, self.topics = services, topics
        self._sent: deque[bytes] = deque(maxlen=64)  # map payloads published (ours)
        self._last: dict[str, bytes] = {}  # floor -> its map payload last published
        self._assigned: dict[str, bytes] = {}  # agent -> its floor message (retained)

    # -- maps ----------------------------------------------------------------------------
    def map_message(self, floor: str, landmarks: list[LandmarkPublic]) -> bytes:
        """The map of `floor` (of the landmarks `landmarks`, every floor's) with its version;
        remembered as ours (`is_ours`)."""
        lms = [
            MapLandmark(id=lm.id, x=lm.x, y=lm.y, z=lm.z) for lm in landmarks if lm.floor == floor
        ]
        body = json.dumps([lm.model_dump() for lm in lms], sort_keys=True).encode()
        map_id = f"{self.topics.site}-{hashlib.sha256(body).hexdigest()[:12]}"
        version = self.services.map_versions.version(floor)
        msg = MapMessage(map_id=map_id, landmarks=lms, floor=floor, version=version).encode()
        self._sent.append(msg)
        return msg

    def maps(
        self, landmarks: list[LandmarkPublic] | None = None, *, changed: bool
    ) -> list[Message]:
        """Every floor's map message (`changed`: only those that differ from the last
        published), and the legacy `map` topic's (the default floor's)."""
        items = landmarks if landmarks is not None else self.services.map.list()
        default = self.services.floors.default()
        out: list[Message] = []
        for floor in self.services.floors.ids():
            msg = self.map_message(floor, items)
            if changed and self._last.get(floor) == msg:
                continue
            self._last[floor] = msg
            out.append((self.topics.floor_map(floor), msg))
            if floor == default:
                out.append((self.topics.map, msg))
        return out

    def floor_map(self, floor: str) -> Message:
        """One floor's map message now."""
        msg = self.map_message(floor, self.services.map.list())
        self._last[floor] = msg
        return self.topics.floor_map(floor), msg

    def is_ours(self, payload: bytes) -> bool:
        """Whether a map seen on a map topic is one this server published."""
        return not payload or payload in self._sent

    # -- the agents' floors --------------------------------------------------------------
    def start_floor(self, status: AgentStatus, robot: str) -> str:
        """The floor a newly seen agent is on: the one it says it localizes on (or starts
        on) when the site has it, else where the site starts that robot."""
        site_floors = self.services.site_floors
        if status.floor is not None and status.floor in site_floors.floors.ids():
            return status.floor
        return site_floors.initial(robot)

    def assign(self, robot: str, floor: str, near: Near | None = None) -> Message:
        """The floor message telling agent `robot` it is on `floor` (near a pose there)."""
        msg = FloorMessage(
            n=time.time_ns(),
            floor=floor,
            version=self.services.map_versions.version(floor),
            near=near,
        ).encode()
        self._assigned[robot] = msg
        return self.topics.floor_assignment(robot), msg

    def assignments(self) -> list[Message]:
        """Every agent's floor message as last sent (to publish again after the broker
        came back: it may have lost its retained messages)."""
        return [(self.topics.floor_assignment(r), m) for r, m in self._assigned.items()]

    def assigned(self, robot: str) -> Message | None:
        """The agent's floor message as last sent, None before the first."""
        msg = self._assigned.get(robot)
        return None if msg is None else (self.topics.floor_assignment(robot), msg)

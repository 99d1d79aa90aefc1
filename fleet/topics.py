"""The MQTT topic layout of a site: irloc's own topics and the VDA 5050 ones.

irloc topics live under `irloc/v1/<site>/` (docs/fleet.md has the table with QoS and
retain flags); VDA 5050 topics under `uagv/v2/<manufacturer>/<serialNumber>/<topic>`. A robot
agent's name is its VDA 5050 serial number. Names are checked: MQTT wildcards (`+`, `#`) and
the level separator `/` cannot be part of a site, manufacturer or robot name.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

IRLOC_ROOT = "irloc/v1"
VDA_INTERFACE = "uagv"
VDA_MAJOR = "v2"
_NAME = re.compile(r"^[A-Za-z0-9_.-]{1,64}$")

QOS_POSE = 0
"""Poses and visualization: a lost one is replaced by the next (at 10 Hz)."""
QOS_STATE = 1
"""Map, LED states, status, connection, LED requests, commands: delivered at least once."""
QOS_CLOCK = 0
"""Clock requests and replies: a late or lost exchange is worthless anyway."""


def check_name(what: str, value: str) -> str:
    """A site, manufacturer or robot name usable as one topic level; ValueError names it."""
    if not _NAME.match(value):
        raise ValueError(
            f"{what} {value!r}: expected 1-64 characters of letters, digits, '_', '.', '-' "
            "(no '/', '+', '#')"
        )
    return value


@dataclass(frozen=True)
class SiteTopics:
    """The irloc topics of one site (`irloc/v1/<site>/...`)."""

    site: str

    def __post_init__(self) -> None:
        check_name("site", self.site)

    @property
    def root(self) -> str:
        return f"{IRLOC_ROOT}/{self.site}"

    # site -> agents
    @property
    def map(self) -> str:
        """The landmark map (retained)."""
        return f"{self.root}/map"

    @property
    def leds(self) -> str:
        """Every confirmed or announced LED state, in order (retained: the last one)."""
        return f"{self.root}/leds"

    @property
    def server(self) -> str:
        """The site server's presence, `{"state": "ONLINE" | "OFFLINE"}` (retained, will)."""
        return f"{self.root}/server"

    def alert(self, kind: str, subject: str) -> str:
        """One alert (retained while it is active; docs/alerts.md)."""
        return (
            f"{self.root}/alerts/{check_name('alert kind', kind)}/{check_name('subject', subject)}"
        )

    @property
    def alerts_wildcard(self) -> str:
        """Every alert of the site."""
        return f"{self.root}/alerts/+/+"

    def is_alert(self, topic: str) -> bool:
        return topic.startswith(f"{self.root}/alerts/")

    def clock_reply(self, robot: str) -> str:
        return f"{self.agent(robot)}/clock/reply"

    def command(self, robot: str) -> str:
        """Operator commands for one agent (relocalize)."""
        return f"{self.agent(robot)}/command"

    # agents -> site
    @property
    def clock_request(self) -> str:
        return f"{self.root}/clock/request"

    def agent(self, robot: str) -> str:
        return f"{self.root}/agents/{check_name('robot name', robot)}"

    def pose(self, robot: str) -> str:
        return f"{self.agent(robot)}/pose"

    def status(self, robot: str) -> str:
        """The agent's camera, wheels, clock offset and counters (retained)."""
        return f"{self.agent(robot)}/status"

    def led_request(self, robot: str) -> str:
        return f"{self.agent(robot)}/led_request"

    @property
    def agents_wildcard(self) -> str:
        """Every agent's pose, status and LED request (what the server subscribes to)."""
        return f"{self.root}/agents/+/+"

    def agent_of(self, topic: str) -> tuple[str, str] | None:
        """(robot, leaf) of an agent topic `.../agents/<robot>/<leaf>`, else None."""
        prefix = f"{self.root}/agents/"
        if not topic.startswith(prefix):
            return None
        robot, sep, leaf = topic[len(prefix) :].partition("/")
        if not sep or not _NAME.match(robot):
            return None
        return robot, leaf


def vda_topic(manufacturer: str, serial_number: str, subtopic: str) -> str:
    """`uagv/v2/<manufacturer>/<serialNumber>/<subtopic>` (VDA 5050 2.x, sec. 6.1)."""
    check_name("VDA 5050 manufacturer", manufacturer)
    check_name("VDA 5050 serial number", serial_number)
    return f"{VDA_INTERFACE}/{VDA_MAJOR}/{manufacturer}/{serial_number}/{subtopic}"


def vda_connection_wildcard(manufacturer: str) -> str:
    """Every robot's `connection` topic of one manufacturer."""
    check_name("VDA 5050 manufacturer", manufacturer)
    return f"{VDA_INTERFACE}/{VDA_MAJOR}/{manufacturer}/+/connection"


def vda_serial_of(topic: str) -> str | None:
    """The serial number of a VDA 5050 topic, else None."""
    parts = topic.split("/")
    if len(parts) != 5 or parts[0] != VDA_INTERFACE or parts[1] != VDA_MAJOR:
        return None
    return parts[3]

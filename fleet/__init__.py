"""The fleet protocol: MQTT topics and payloads between robot agents and the site server,
VDA 5050 messages, the clock-offset math, and whether a robot's view fits its floor's map
(`fleet.floor_fit`, which the site and the agents both apply). Pure: imports only
`localizer`."""

from fleet.broker import BrokerAddress, parse_broker_url
from fleet.clock import ClockConfig, ClockEstimate, ClockFilter, ClockSample
from fleet.payloads import (
    AgentStatus,
    ClockReply,
    ClockRequest,
    CommandMessage,
    LedRequestMessage,
    LedStateMessage,
    MapMessage,
    PayloadError,
    PoseMessage,
    ServerState,
    decode,
)
from fleet.topics import SiteTopics, vda_topic

__all__ = [
    "AgentStatus",
    "BrokerAddress",
    "ClockConfig",
    "ClockEstimate",
    "ClockFilter",
    "ClockReply",
    "ClockRequest",
    "ClockSample",
    "CommandMessage",
    "LedRequestMessage",
    "LedStateMessage",
    "MapMessage",
    "PayloadError",
    "PoseMessage",
    "ServerState",
    "SiteTopics",
    "decode",
    "parse_broker_url",
    "vda_topic",
]

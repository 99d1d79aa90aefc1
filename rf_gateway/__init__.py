"""rf_gateway: switch and read the landmarks over the virtual site's radio or an XBee network."""

from rf_gateway.battery import BatteryMonitorConfig, BatteryReading
from rf_gateway.config import GatewayConfig
from rf_gateway.errors import (
    LandmarkUnreachableError,
    RadioTimeout,
    RemoteCommandError,
    RfGatewayError,
    TransportUnavailable,
    UnknownLandmarkError,
)
from rf_gateway.events import (
    GatewayEvent,
    LandmarkReachable,
    LandmarkUnreachable,
    LowBattery,
    TransportStateChanged,
)
from rf_gateway.factory import make_transport
from rf_gateway.gateway import Gateway
from rf_gateway.scheduler import Priority, QueueFullError
from rf_gateway.sim_transport import SimTransport
from rf_gateway.transport import (
    DiscoveredRadio,
    SimRadioSpec,
    Transport,
    XBeeRadioSpec,
    normalize_address,
    parse_radio_spec,
)
from rf_gateway.xbee_transport import XBeeTransport, XBeeTransportConfig

__all__ = [
    "BatteryMonitorConfig",
    "BatteryReading",
    "DiscoveredRadio",
    "Gateway",
    "GatewayConfig",
    "GatewayEvent",
    "LandmarkReachable",
    "LandmarkUnreachable",
    "LandmarkUnreachableError",
    "LowBattery",
    "Priority",
    "QueueFullError",
    "RadioTimeout",
    "RemoteCommandError",
    "RfGatewayError",
    "SimRadioSpec",
    "SimTransport",
    "Transport",
    "TransportStateChanged",
    "TransportUnavailable",
    "UnknownLandmarkError",
    "XBeeRadioSpec",
    "XBeeTransport",
    "XBeeTransportConfig",
    "make_transport",
    "normalize_address",
    "parse_radio_spec",
]

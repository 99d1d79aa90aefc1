"""Events the gateway publishes besides `localizer.events.LedsChanged`."""

from __future__ import annotations

from dataclasses import dataclass

from rf_gateway.transport import TransportState


@dataclass(frozen=True)
class LandmarkUnreachable:
    """A landmark stopped answering: `tries` commands in a row failed (at `t_ns`)."""

    t_ns: int
    landmark_id: int
    address: str
    tries: int


@dataclass(frozen=True)
class LandmarkReachable:
    """A landmark marked unreachable answered again."""

    t_ns: int
    landmark_id: int
    address: str


@dataclass(frozen=True)
class LowBattery:
    """A supply reading at or below the low-battery threshold.

    Attributes:
        supply_mv: the reading, millivolts.
        days_left: estimated days until the cut-off voltage, None when unknown.
    """

    t_ns: int
    landmark_id: int
    supply_mv: int
    days_left: float | None


@dataclass(frozen=True)
class TransportStateChanged:
    """The radio link changed state ("open", "reopening", "closed", ...)."""

    t_ns: int
    state: TransportState


GatewayEvent = LandmarkUnreachable | LandmarkReachable | LowBattery | TransportStateChanged

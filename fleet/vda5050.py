"""VDA 5050 v2.1 messages of a robot: `visualization` (its pose) and `connection` (ONLINE,
OFFLINE, and the last will CONNECTIONBROKEN).

Mapping of a pose: `agvPosition.x/y/theta` are the pose (metres, radians, REP-103, world
frame = `mapId`); `positionInitialized` is true once the localizer has a pose it keeps up
(landmark or dead-reckoning mode); `deviationRange` is the radius holding the position with
95 % probability (the pose's `deviation_m`, or from its covariance), metres;
`localizationScore` is the pose's 0-1 quality (docs/quality.md). `velocity` is left out
(the localizer estimates the pose, not the speed). Messages are dicts ready for
`json.dumps`; the official JSON schemas validate them (tests/fleet/test_vda5050.py).
"""

from __future__ import annotations

import datetime as dt
from dataclasses import dataclass, field
from typing import Any, Literal

import numpy as np
import numpy.typing as npt

from localizer.events import Mode
from localizer.pose_quality import deviation_radius_m

VDA5050_VERSION = "2.1.0"
ConnectionState = Literal["ONLINE", "OFFLINE", "CONNECTIONBROKEN"]


def deviation_range_m(covariance: npt.ArrayLike) -> float:
    """Radius of the circle holding the position with 95 % probability, metres;
    covariance of (x, y, theta), shape (3, 3) (`pose_quality.deviation_radius_m`)."""
    return deviation_radius_m(np.asarray(covariance, dtype=np.float64))


def iso8601_utc(wall_ns: int) -> str:
    """`1991-03-11T11:40:03.120Z` from a Unix time in nanoseconds."""
    t = dt.datetime.fromtimestamp(wall_ns / 1e9, tz=dt.UTC)
    return t.strftime("%Y-%m-%dT%H:%M:%S.") + f"{t.microsecond // 1000:03d}Z"


def position_initialized(mode: Mode) -> bool:
    """VDA 5050's `positionInitialized`: the localizer keeps a pose up."""
    return mode in ("landmark", "dead_reckoning")


@dataclass
class HeaderIds:
    """`headerId` counters, one per (robot, topic), incremented with every message sent."""

    _next: dict[tuple[str, str], int] = field(default_factory=dict, repr=False)

    def take(self, robot: str, topic: str) -> int:
        n = self._next.get((robot, topic), 0)
        self._next[(robot, topic)] = n + 1
        return n


def header(header_id: int, wall_ns: int, manufacturer: str, serial_number: str) -> dict[str, Any]:
    """The header every VDA 5050 message starts with."""
    return {
        "headerId": header_id,
        "timestamp": iso8601_utc(wall_ns),
        "version": VDA5050_VERSION,
        "manufacturer": manufacturer,
        "serialNumber": serial_number,
    }


def visualization_message(
    header_id: int,
    wall_ns: int,
    manufacturer: str,
    serial_number: str,
    *,
    map_id: str,
    mode: Mode,
    pose: tuple[float, float, float] | None,
    covariance: npt.ArrayLike | None = None,
    quality: float | None = None,
    deviation_m: float | None = None,
) -> dict[str, Any]:
    """A `visualization` message; `agvPosition` only when there is a pose (x, y, theta);
    `deviationRange` from `deviation_m` (else the covariance), `localizationScore` from
    `quality` (0-1)."""
    msg = header(header_id, wall_ns, manufacturer, serial_number)
    if pose is not None:
        x, y, theta = pose
        position: dict[str, Any] = {
            "x": x,
            "y": y,
            "theta": theta,
            "mapId": map_id,
            "positionInitialized": position_initialized(mode),
        }
        if deviation_m is None and covariance is not None:
            deviation_m = deviation_range_m(covariance)
        if deviation_m is not None:
            position["deviationRange"] = float(f"{deviation_m:.4g}")
        if quality is not None:
            position["localizationScore"] = round(min(max(quality, 0.0), 1.0), 3)
        msg["agvPosition"] = position
    return msg


def connection_message(
    header_id: int,
    wall_ns: int,
    manufacturer: str,
    serial_number: str,
    state: ConnectionState,
) -> dict[str, Any]:
    """A `connection` message (published retained, QoS 1; CONNECTIONBROKEN is the will)."""
    return {**header(header_id, wall_ns, manufacturer, serial_number), "connectionState": state}

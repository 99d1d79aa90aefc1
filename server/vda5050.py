"""Poses in the shape of VDA 5050 (v2) `visualization` messages, for fleet software.

Sites with many robots will publish poses over MQTT to a master control; VDA 5050 is the
common interface there. This module is the pure part: one `PoseUpdate` -> one message (a
dict ready for `json.dumps`) and its topic; the MQTT client is left to the deployment.

Mapping: `agvPosition.x/y/theta` are the pose (metres, radians, REP-103, world frame =
`mapId`); `positionInitialized` is true once the localizer has a pose it keeps up (landmark
or dead-reckoning mode); `deviationRange` is the radius holding the position with 95 %
probability, from the covariance, metres. `velocity` is left out (the localizer estimates
the pose, not the speed).
"""

from __future__ import annotations

import datetime as dt
import math
from dataclasses import dataclass, field
from typing import Any

import numpy as np

from server.poses import PoseUpdate

VDA5050_VERSION = "2.0.0"
INTERFACE_NAME = "uagv"
CHI2_2DOF_95 = 5.991  # 95 % point of chi-square with 2 degrees of freedom


def deviation_range_m(covariance: np.ndarray) -> float:
    """Radius of the circle holding the position with 95 % probability (bounded by the
    major axis of the error ellipse), metres; covariance of (x, y, theta), shape (3, 3)."""
    major = float(np.linalg.eigvalsh(np.asarray(covariance, float)[:2, :2])[-1])
    return math.sqrt(CHI2_2DOF_95 * max(major, 0.0))


def iso8601_utc(wall_ns: int) -> str:
    """`1991-03-11T11:40:03.120Z` from a Unix time in nanoseconds."""
    t = dt.datetime.fromtimestamp(wall_ns / 1e9, tz=dt.UTC)
    return t.strftime("%Y-%m-%dT%H:%M:%S.") + f"{t.microsecond // 1000:03d}Z"


def visualization_topic(manufacturer: str, serial_number: str) -> str:
    """The MQTT topic `uagv/v2/<manufacturer>/<serialNumber>/visualization`."""
    for name, value in (("manufacturer", manufacturer), ("serial number", serial_number)):
        if not value or any(c in value for c in "/+#"):
            raise ValueError(f"VDA 5050 {name} must be non-empty without '/', '+', '#': {value!r}")
    major = VDA5050_VERSION.split(".")[0]
    return f"{INTERFACE_NAME}/v{major}/{manufacturer}/{serial_number}/visualization"


@dataclass
class VisualizationEncoder:
    """Encode pose updates as VDA 5050 `visualization` messages, one `headerId` sequence
    per robot (incremented with every message, as the standard asks).

    Args:
        manufacturer: the AGV manufacturer named in every message.
        map_id: the map the poses refer to (the site's landmark map).
    """

    manufacturer: str
    map_id: str
    _header_ids: dict[str, int] = field(default_factory=dict, repr=False)

    def encode(self, update: PoseUpdate) -> dict[str, Any]:
        """The message for one pose update (the robot's name is its serial number)."""
        header = self._header_ids.get(update.robot, -1) + 1
        self._header_ids[update.robot] = header
        msg: dict[str, Any] = {
            "headerId": header,
            "timestamp": iso8601_utc(update.computed_wall_ns),
            "version": VDA5050_VERSION,
            "manufacturer": self.manufacturer,
            "serialNumber": update.robot,
        }
        if update.x is not None and update.y is not None and update.theta is not None:
            position: dict[str, Any] = {
                "x": update.x,
                "y": update.y,
                "theta": update.theta,
                "mapId": self.map_id,
                "positionInitialized": update.mode in ("landmark", "dead_reckoning"),
            }
            if update.covariance is not None:
                position["deviationRange"] = deviation_range_m(update.covariance)
            msg["agvPosition"] = position
        return msg

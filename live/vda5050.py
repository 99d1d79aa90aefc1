"""Pose-bus updates as VDA 5050 v2 `visualization` messages (the message itself is built by
`fleet.vda5050`, which the on-robot agent publishes with; this adds the per-robot
`headerId` sequence and the topic for poses computed on the server)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Any

from fleet.topics import vda_topic
from fleet.vda5050 import (
    VDA5050_VERSION,
    HeaderIds,
    deviation_range_m,
    iso8601_utc,
    visualization_message,
)
from live.poses import PoseUpdate

__all__ = [
    "VDA5050_VERSION",
    "VisualizationEncoder",
    "deviation_range_m",
    "iso8601_utc",
    "visualization_topic",
]


def visualization_topic(manufacturer: str, serial_number: str) -> str:
    """The MQTT topic `uagv/v2/<manufacturer>/<serialNumber>/visualization`."""
    return vda_topic(manufacturer, serial_number, "visualization")


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
    _headers: HeaderIds = field(default_factory=HeaderIds, repr=False)

    def encode(self, update: PoseUpdate) -> dict[str, Any]:
        """The message for one pose update (the robot's name is its serial number)."""
        pose = None
        if update.x is not None and update.y is not None and update.theta is not None:
            pose = (update.x, update.y, update.theta)
        return visualization_message(
            self._headers.take(update.robot, "visualization"),
            update.computed_wall_ns,
            self.manufacturer,
            update.robot,
            map_id=self.map_id,
            mode=update.mode,
            pose=pose,
            covariance=update.covariance,
            quality=update.quality,
            deviation_m=update.deviation_m,
        )

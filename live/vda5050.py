"""Pose-bus updates as VDA 5050 v2 `visualization` messages (the message itself is built by
`fleet.vda5050`, which the on-robot agent publishes with; this adds the per-robot
`headerId` sequence and the topic for poses computed on the server)."""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
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
    "InitPosition",
    "VisualizationEncoder",
    "deviation_range_m",
    "init_positions",
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
        map_id: the site's name (kept for callers; each pose's `mapId` is its floor, the
            ID of that floor's map: `GET /api/v1/floors/{mapId}/map`).
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
            map_id=update.floor,
            mode=update.mode,
            pose=pose,
            covariance=update.covariance,
            quality=update.quality,
            deviation_m=update.deviation_m,
        )


@dataclass(frozen=True)
class InitPosition:
    """A VDA 5050 `initPosition` instant action: the robot is at (x, y, theta) on the map
    `map_id` (here: a floor ID), e.g. as it leaves the lift (metres, radians)."""

    action_id: str
    map_id: str
    x: float
    y: float
    theta: float


def init_positions(
    actions: Sequence[tuple[str, str, Mapping[str, object]]],
) -> list[InitPosition]:
    """The `initPosition` actions of an `instantActions` message, given as (actionType,
    actionId, {key: value} of its actionParameters).

    Raises:
        ValueError: naming the action and the missing or bad parameter, or an action type
            this server does not carry out (nothing is done then).
    """
    out = []
    for kind, action_id, params in actions:
        if kind != "initPosition":
            raise ValueError(
                f"action {action_id!r}: actionType {kind!r} is not supported (initPosition is)"
            )
        values: dict[str, float] = {}
        for key in ("x", "y", "theta"):
            v = params.get(key)
            if isinstance(v, bool) or not isinstance(v, int | float) or not math.isfinite(v):
                raise ValueError(f"action {action_id!r}: {key} must be a number, got {v!r}")
            values[key] = float(v)
        map_id = params.get("mapId")
        if not isinstance(map_id, str) or not map_id:
            raise ValueError(f"action {action_id!r}: mapId must name a floor, got {map_id!r}")
        out.append(InitPosition(action_id, map_id, values["x"], values["y"], values["theta"]))
    return out

"""Site events (low battery, landmark unreachable, robot lost, map changed): stored in the
database, published on the event bus (SSE stream, viewer) and logged (with `event`, `robot`,
`landmark` as structured fields)."""

from __future__ import annotations

import json
import logging
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from pubsub.bus import Bus
from store.log import EventLog

EVENT_KINDS = (
    "low_battery",
    "landmark_unreachable",
    "landmark_reachable",
    "robot_lost",
    "robot_localized",
    "map_changed",
    "radio_state",
    "led_request_failed",
    "robot_connected",
    "robot_disconnected",
    "clock_offset",
    "black_box_saved",
)
WARNING_EVENTS = frozenset(
    {
        "low_battery",
        "landmark_unreachable",
        "robot_lost",
        "led_request_failed",
        "radio_state",
        "clock_offset",
    }
)
"""Kinds logged as warnings (the others as info)."""
log = logging.getLogger(__name__)


@dataclass(frozen=True)
class SiteEvent:
    """One event.

    Attributes:
        id: database id; t: UTC time; kind: one of `EVENT_KINDS`; message: for people;
        robot, landmark_id: what it is about, when it applies; data: details.
    """

    id: int
    t: datetime
    kind: str
    message: str
    robot: str | None = None
    landmark_id: int | None = None
    data: dict[str, Any] = field(default_factory=dict)

    def to_dict(self) -> dict[str, Any]:
        return {
            "id": self.id,
            "t": self.t.isoformat(),
            "kind": self.kind,
            "message": self.message,
            "robot": self.robot,
            "landmark_id": self.landmark_id,
            "data": self.data,
        }

    def json(self) -> str:
        return json.dumps(self.to_dict(), separators=(",", ":"))


class EventHub:
    """Record an event in the database, then publish it (thread-safe)."""

    def __init__(self, log: EventLog, maxsize: int = 256) -> None:
        self.log = log
        self.bus: Bus[SiteEvent] = Bus(maxsize)

    def emit(
        self,
        kind: str,
        message: str,
        *,
        robot: str | None = None,
        landmark_id: int | None = None,
        data: dict[str, Any] | None = None,
    ) -> SiteEvent:
        rec = self.log.add_event(kind, message, robot=robot, landmark_id=landmark_id, data=data)
        extra: dict[str, Any] = {"event": kind}
        if robot is not None:
            extra["robot"] = robot
        if landmark_id is not None:
            extra["landmark"] = landmark_id
        level = logging.WARNING if kind in WARNING_EVENTS else logging.INFO
        log.log(level, "%s", message, extra=extra)
        event = SiteEvent(rec.id or 0, rec.t, kind, message, robot, landmark_id, rec.data)
        self.bus.publish(event)
        return event

    def recent(self, limit: int = 100) -> list[SiteEvent]:
        """The newest events first."""
        return [
            SiteEvent(r.id or 0, r.t, r.kind, r.message, r.robot, r.landmark_id, r.data)
            for r in self.log.events(limit)
        ]

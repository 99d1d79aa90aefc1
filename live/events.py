"""Site events (low battery, landmark unreachable, robot lost, map changed): stored in the
database, published on the event bus (SSE stream, viewer) and logged (with `event`, `robot`,
`landmark` as structured fields)."""

from __future__ import annotations

import json
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Literal, get_args

from live.event_writer import EventWriter, PendingEvent
from pubsub.bus import Bus
from store.log import EventLog

EventKind = Literal[
    "low_battery",
    "landmark_unreachable",
    "landmark_reachable",
    "robot_lost",
    "robot_localized",
    "robot_identifying",
    "map_changed",
    "radio_state",
    "led_request_failed",
    "robot_connected",
    "robot_disconnected",
    "clock_offset",
    "map_proposal_rejected",
    "zone_enter",
    "zone_exit",
    "zone_dwell",
    "robot_floor_changed",
    "floor_proposed",
    "agent_map_outdated",
    "recording_stopped",
    "site_thread_restarted",
    "fleet_intrusion",
    "black_box_saved",
]
"""What an event is about (the API's enumerated type)."""
EVENT_KINDS: tuple[str, ...] = get_args(EventKind)
WARNING_EVENTS = frozenset(
    {
        "low_battery",
        "landmark_unreachable",
        "robot_lost",
        "led_request_failed",
        "radio_state",
        "clock_offset",
        "agent_map_outdated",
        "recording_stopped",
        "site_thread_restarted",
        "fleet_intrusion",
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
    """Log an event at once, then store it in the database and publish it from the event
    writer's thread (`live.event_writer`): whoever emits never waits on the database, and a
    failing database loses no event and stops nothing (thread-safe)."""

    def __init__(self, log: EventLog, maxsize: int = 256) -> None:
        self.log = log
        self.bus: Bus[SiteEvent] = Bus(maxsize)
        self.writer = EventWriter(log, self._publish)

    def _publish(self, ev: PendingEvent, event_id: int) -> None:
        self.bus.publish(
            SiteEvent(event_id, ev.t, ev.kind, ev.message, ev.robot, ev.landmark_id, ev.data)
        )

    def flush(self, timeout_s: float = 2.0) -> bool:
        """Wait until the events emitted so far are stored (or kept for a failing database)."""
        return self.writer.flush(timeout_s)

    def close(self) -> None:
        self.writer.close()

    def emit(
        self,
        kind: EventKind,
        message: str,
        *,
        robot: str | None = None,
        landmark_id: int | None = None,
        data: dict[str, Any] | None = None,
    ) -> None:
        if kind not in EVENT_KINDS:  # the API lists the kinds: a new one is added there
            raise ValueError(f"event kind {kind!r} is not one of EventKind: {EVENT_KINDS}")
        pending = PendingEvent(kind, message, robot, landmark_id, dict(data or {}))
        extra: dict[str, Any] = {"event": kind}
        if robot is not None:
            extra["robot"] = robot
        if landmark_id is not None:
            extra["landmark"] = landmark_id
        level = logging.WARNING if kind in WARNING_EVENTS else logging.INFO
        log.log(level, "%s", message, extra=extra)
        self.writer.submit(pending)

    def recent(
        self,
        limit: int = 100,
        *,
        kinds: Sequence[str] | None = None,
        before_id: int | None = None,
        after_id: int | None = None,
        robot: str | None = None,
    ) -> list[SiteEvent]:
        """The newest events first (`after_id`: the oldest after it first), filtered; those
        emitted before the call included (the event writer is waited for, 1 s at most)."""
        self.writer.flush(1.0)
        return [
            SiteEvent(r.id or 0, r.t, r.kind, r.message, r.robot, r.landmark_id, r.data)
            for r in self.log.events(
                limit, kinds, before_id=before_id, after_id=after_id, robot=robot
            )
        ]

"""Site events (low battery, landmark unreachable, robot lost, map changed): stored in the
database, published on the event bus (SSE stream, viewer) and logged (with `event`, `robot`,
`landmark` as structured fields)."""

from __future__ import annotations

import json
import logging
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Literal, Protocol, get_args

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
    "alert_raised",
    "alert_resolved",
    "cells_replaced",
    "black_box_saved",
]
"""What an event is about (the API's enumerated type). A new kind is added here: every
emitter is typed with it (`EventHub.emit`, `EmitEvent`), so mypy refuses a kind not listed."""
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
        "alert_raised",
    }
)
"""Kinds logged as warnings (the others as info)."""
log = logging.getLogger(__name__)


class EmitEvent(Protocol):
    """Something that emits a site event: `EventHub.emit`, or what hands it on (off a loop,
    say); typed so that mypy checks every kind emitted through it."""

    def __call__(
        self,
        kind: EventKind,
        message: str,
        *,
        robot: str | None = None,
        data: dict[str, Any] | None = None,
    ) -> None: ...


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
        """Log the event and queue it for storing and publishing; returns at once.

        `kind` is checked by mypy (`EventKind`). One that is not listed all the same (from
        code outside the type checker) is logged as an error with its message, and neither
        stored nor published (the API could not list it): the site carries on."""
        if kind not in EVENT_KINDS:
            log.error(
                "event of unlisted kind %r not stored (add it to EventKind): %s", kind, message
            )
            return
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

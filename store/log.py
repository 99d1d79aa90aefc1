"""Battery readings and site events in the database."""

from __future__ import annotations

from collections.abc import Sequence
from datetime import datetime
from typing import Any

from sqlalchemy import Engine
from sqlmodel import Session, col, select

from store.models import BatteryRecord, EventRecord, Landmark


class EventLog:
    """Append-only history: battery readings per landmark and site events."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    def add_battery(self, landmark_id: int, supply_mv: int, t: datetime | None = None) -> bool:
        """Store one reading; False (nothing stored) when the landmark is gone."""
        with Session(self.engine) as s:
            if s.get(Landmark, landmark_id) is None:
                return False
            rec = BatteryRecord(landmark_id=landmark_id, supply_mv=int(supply_mv))
            if t is not None:
                rec.t = t
            s.add(rec)
            s.commit()
            return True

    def battery_history(
        self, landmark_id: int, limit: int = 500, *, since: datetime | None = None
    ) -> list[BatteryRecord]:
        """Readings of one landmark, oldest first (the newest `limit`; from `since` on)."""
        with Session(self.engine) as s:
            q = (
                select(BatteryRecord)
                .where(BatteryRecord.landmark_id == landmark_id)
                .order_by(col(BatteryRecord.t).desc())
                .limit(limit)
            )
            if since is not None:
                q = q.where(col(BatteryRecord.t) >= since)
            return list(reversed(list(s.exec(q))))

    def last_event(self, kind: str, *, landmark_id: int | None = None) -> EventRecord | None:
        """The newest event of this kind (about this landmark), None when there is none."""
        with Session(self.engine) as s:
            q = select(EventRecord).where(EventRecord.kind == kind)
            if landmark_id is not None:
                q = q.where(EventRecord.landmark_id == landmark_id)
            return s.exec(q.order_by(col(EventRecord.id).desc()).limit(1)).first()

    def add_event(
        self,
        kind: str,
        message: str,
        *,
        robot: str | None = None,
        landmark_id: int | None = None,
        data: dict[str, Any] | None = None,
        t: datetime | None = None,
    ) -> EventRecord:
        with Session(self.engine) as s:
            rec = EventRecord(
                kind=kind, message=message, robot=robot, landmark_id=landmark_id, data=data or {}
            )
            if t is not None:
                rec.t = t
            s.add(rec)
            s.commit()
            s.refresh(rec)
            return rec

    def events(
        self,
        limit: int = 100,
        kind: str | Sequence[str] | None = None,
        *,
        before_id: int | None = None,
        after_id: int | None = None,
        robot: str | None = None,
    ) -> list[EventRecord]:
        """The newest events first (with `after_id`: the oldest after it first), of these
        kinds and this robot, older than `before_id` (paging back) or newer than
        `after_id` (catching up, as an SSE client does with Last-Event-ID)."""
        with Session(self.engine) as s:
            order = (
                col(EventRecord.id).asc() if after_id is not None else col(EventRecord.id).desc()
            )
            q = select(EventRecord).order_by(order).limit(limit)
            if isinstance(kind, str):
                q = q.where(EventRecord.kind == kind)
            elif kind is not None:
                q = q.where(col(EventRecord.kind).in_(list(kind)))
            if before_id is not None:
                q = q.where(col(EventRecord.id) < before_id)
            if after_id is not None:
                q = q.where(col(EventRecord.id) > after_id)
            if robot is not None:
                q = q.where(EventRecord.robot == robot)
            return list(s.exec(q))

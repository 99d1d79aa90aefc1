"""Battery readings and site events in the database."""

from __future__ import annotations

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

    def battery_history(self, landmark_id: int, limit: int = 500) -> list[BatteryRecord]:
        """Readings of one landmark, oldest first (the newest `limit`)."""
        with Session(self.engine) as s:
            q = (
                select(BatteryRecord)
                .where(BatteryRecord.landmark_id == landmark_id)
                .order_by(col(BatteryRecord.t).desc())
                .limit(limit)
            )
            return list(reversed(list(s.exec(q))))

    def add_event(
        self,
        kind: str,
        message: str,
        *,
        robot: str | None = None,
        landmark_id: int | None = None,
        data: dict[str, Any] | None = None,
    ) -> EventRecord:
        with Session(self.engine) as s:
            rec = EventRecord(
                kind=kind, message=message, robot=robot, landmark_id=landmark_id, data=data or {}
            )
            s.add(rec)
            s.commit()
            s.refresh(rec)
            return rec

    def events(self, limit: int = 100, kind: str | None = None) -> list[EventRecord]:
        """The newest events first."""
        with Session(self.engine) as s:
            q = select(EventRecord).order_by(col(EventRecord.id).desc()).limit(limit)
            if kind is not None:
                q = q.where(EventRecord.kind == kind)
            return list(s.exec(q))

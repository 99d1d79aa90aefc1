"""Zones and the robots' pose history in the database (`ZoneRecord`, `PoseRecord`)."""

from __future__ import annotations

import builtins
import threading
from collections.abc import Callable, Sequence
from datetime import datetime

from sqlalchemy import Engine, delete
from sqlalchemy.exc import IntegrityError
from sqlmodel import Session, col, select

from store.errors import ConflictError, NotFoundError
from store.models import PoseRecord, ZoneRecord


def check_polygon(points: Sequence[Sequence[float]], *, source: str = "polygon") -> None:
    """ValueError naming what is wrong: fewer than 3 points, a point not (x, y), a
    non-finite coordinate, or no area."""
    if len(points) < 3:
        raise ValueError(f"{source}: a zone needs at least 3 points (x, y), got {len(points)}")
    for i, p in enumerate(points):
        if len(p) != 2 or not all(abs(float(v)) < 1e6 for v in p):
            raise ValueError(f"{source}[{i}]: expected [x, y] in metres, got {list(p)!r}")
    area2 = sum(
        points[i][0] * points[(i + 1) % len(points)][1]
        - points[(i + 1) % len(points)][0] * points[i][1]
        for i in range(len(points))
    )
    if abs(area2) < 1e-6:
        raise ValueError(f"{source}: the points enclose no area")


class ZoneStore:
    """The site's zones (thread-safe); `add_listener` hears every change."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self._listeners: list[Callable[[builtins.list[ZoneRecord]], None]] = []
        self._lock = threading.Lock()

    def list(self) -> builtins.list[ZoneRecord]:
        with Session(self.engine, expire_on_commit=False) as s:
            return builtins.list(s.exec(select(ZoneRecord).order_by(col(ZoneRecord.id))))

    def get(self, zone_id: int) -> ZoneRecord:
        with Session(self.engine, expire_on_commit=False) as s:
            z = s.get(ZoneRecord, zone_id)
        if z is None:
            names = ", ".join(f"{r.id} ({r.name})" for r in self.list()) or "none"
            raise NotFoundError(f"no zone {zone_id}; zones: {names}")
        return z

    def create(
        self,
        name: str,
        polygon: Sequence[Sequence[float]],
        *,
        floor: str = "",
        dwell_s: float | None = None,
    ) -> ZoneRecord:
        check_polygon(polygon)
        rec = ZoneRecord(
            name=name,
            floor=floor,
            dwell_s=dwell_s,
            polygon=[[float(x), float(y)] for x, y in polygon],
        )
        with Session(self.engine, expire_on_commit=False) as s:
            s.add(rec)
            try:
                s.commit()
            except IntegrityError:
                raise ConflictError(f"a zone named {name!r} exists already") from None
            s.refresh(rec)
        self._changed()
        return rec

    def delete(self, zone_id: int) -> None:
        with Session(self.engine) as s:
            z = s.get(ZoneRecord, zone_id)
            if z is None:
                raise NotFoundError(f"no zone {zone_id}")
            s.delete(z)
            s.commit()
        self._changed()

    def add_listener(self, fn: Callable[[builtins.list[ZoneRecord]], None]) -> None:
        with self._lock:
            self._listeners.append(fn)

    def _changed(self) -> None:
        zones = self.list()
        with self._lock:
            listeners = builtins.list(self._listeners)
        for fn in listeners:
            fn(zones)


class PoseHistory:
    """Kept poses: written in batches, read by robot and time range, pruned by age."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    def add(self, records: Sequence[PoseRecord]) -> None:
        if not records:
            return
        with Session(self.engine) as s:
            s.add_all(records)
            s.commit()

    def query(
        self,
        *,
        robot: str | None = None,
        since: datetime | None = None,
        until: datetime | None = None,
        limit: int = 10_000,
    ) -> builtins.list[PoseRecord]:
        """Poses oldest first, of `robot` (None: all), in [since, until)."""
        with Session(self.engine, expire_on_commit=False) as s:
            q = select(PoseRecord).order_by(col(PoseRecord.t), col(PoseRecord.id)).limit(limit)
            if robot is not None:
                q = q.where(PoseRecord.robot == robot)
            if since is not None:
                q = q.where(col(PoseRecord.t) >= since)
            if until is not None:
                q = q.where(col(PoseRecord.t) < until)
            return builtins.list(s.exec(q))

    def prune(self, older_than: datetime) -> int:
        """Remove poses older than `older_than`; how many."""
        with Session(self.engine) as s:
            result = s.exec(delete(PoseRecord).where(col(PoseRecord.t) < older_than))
            s.commit()
            return int(result.rowcount or 0)

"""Zones and the robots' pose history in the database (`ZoneRecord`, `PoseRecord`)."""

from __future__ import annotations

import builtins
import threading
from collections.abc import Callable, Sequence
from datetime import datetime

from sqlalchemy import ColumnElement, Engine, delete, func
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

    def update(
        self,
        zone_id: int,
        *,
        name: str | None = None,
        polygon: Sequence[Sequence[float]] | None = None,
        floor: str | None = None,
        dwell_s: float | None = None,
        clear_dwell: bool = False,
    ) -> ZoneRecord:
        """Change the fields given (None keeps one; `clear_dwell` drops the dwell limit);
        NotFoundError, ConflictError (the name is taken), ValueError (a bad polygon)."""
        if polygon is not None:
            check_polygon(polygon)
        with Session(self.engine, expire_on_commit=False) as s:
            z = s.get(ZoneRecord, zone_id)
            if z is None:
                raise NotFoundError(f"no zone {zone_id}")
            if name is not None:
                z.name = name
            if polygon is not None:
                z.polygon = [[float(x), float(y)] for x, y in polygon]
            if floor is not None:
                z.floor = floor
            if clear_dwell:
                z.dwell_s = None
            elif dwell_s is not None:
                z.dwell_s = dwell_s
            s.add(z)
            try:
                s.commit()
            except IntegrityError:
                raise ConflictError(f"a zone named {name!r} exists already") from None
            s.refresh(z)
        self._changed()
        return z

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


def _conditions(
    robot: str | None, since: datetime | None, until: datetime | None, floor: str | None
) -> builtins.list[ColumnElement[bool]]:
    """The WHERE terms of a history read (None: no bound)."""
    conds: builtins.list[ColumnElement[bool]] = []
    if robot is not None:
        conds.append(col(PoseRecord.robot) == robot)
    if since is not None:
        conds.append(col(PoseRecord.t) >= since)
    if until is not None:
        conds.append(col(PoseRecord.t) < until)
    if floor is not None:
        conds.append(col(PoseRecord.floor) == floor)
    return conds


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
        floor: str | None = None,
    ) -> builtins.list[PoseRecord]:
        """Poses oldest first, of `robot` (None: all), in [since, until), on `floor`
        (None: every floor)."""
        with Session(self.engine, expire_on_commit=False) as s:
            q = select(PoseRecord).order_by(col(PoseRecord.t), col(PoseRecord.id)).limit(limit)
            q = q.where(*_conditions(robot, since, until, floor))
            return builtins.list(s.exec(q))

    def thinned(
        self,
        *,
        robot: str | None = None,
        since: datetime | None = None,
        until: datetime | None = None,
        max_points: int = 5_000,
        floor: str | None = None,
    ) -> tuple[builtins.list[PoseRecord], int]:
        """At most `max_points` poses of [since, until), oldest first, evenly spread over
        the kept ones (every k-th, counted in the database: a week of history is never
        read whole); (the poses, how many are kept in the range)."""
        if max_points < 2:
            raise ValueError(f"history: max_points must be at least 2, got {max_points}")
        conds = _conditions(robot, since, until, floor)
        with Session(self.engine, expire_on_commit=False) as s:
            total = int(s.exec(select(func.count()).select_from(PoseRecord).where(*conds)).one())
            stride = max(1, -(-total // max_points))  # ceil
            if stride == 1:
                q = select(PoseRecord).where(*conds)
            else:
                rn = func.row_number().over(order_by=(col(PoseRecord.t), col(PoseRecord.id)))
                ranked = select(col(PoseRecord.id), rn.label("rn")).where(*conds).subquery()
                q = select(PoseRecord).join(ranked, col(PoseRecord.id) == ranked.c.id)
                q = q.where((ranked.c.rn - 1) % stride == 0)
            q = q.order_by(col(PoseRecord.t), col(PoseRecord.id))
            return builtins.list(s.exec(q)), total

    def cell_counts(
        self,
        cell_m: float,
        *,
        robot: str | None = None,
        since: datetime | None = None,
        until: datetime | None = None,
        floor: str | None = None,
    ) -> tuple[builtins.list[tuple[int, int, int]], int]:
        """Kept poses counted per floor cell, in the database (one row a visited cell, however
        long the range): ([(column, row, count)], poses), cell (i, j) spanning
        [i * cell_m, (i + 1) * cell_m) in x and [j * cell_m, ...) in y."""
        if not cell_m > 0:
            raise ValueError(f"coverage: cell_m must be positive, got {cell_m}")
        conds = _conditions(robot, since, until, floor)
        i = func.floor(col(PoseRecord.x) / cell_m)
        j = func.floor(col(PoseRecord.y) / cell_m)
        q = select(i, j, func.count()).where(*conds).group_by(i, j)
        with Session(self.engine) as s:
            rows = [(int(a), int(b), int(n)) for a, b, n in s.exec(q)]
        return rows, sum(n for _, _, n in rows)

    def prune(self, older_than: datetime) -> int:
        """Remove poses older than `older_than`; how many."""
        with Session(self.engine) as s:
            result = s.exec(delete(PoseRecord).where(col(PoseRecord.t) < older_than))
            s.commit()
            return int(result.rowcount or 0)

"""Versioned floor maps: each floor's map has a version and a content hash that change with
every accepted edit of that floor (and stay put otherwise); old versions are kept, served
and can be restored (an audited, undoable step).

The versions follow the landmark map: after every committed change (`MapRepository`'s
listeners) `sync` compares each floor's content hash (`store.floors.map_hash`) with its
latest version and records a new version, with the content, for each floor that changed,
naming the audit record (actor and action) that changed it. `sync` also runs when the
database is opened, so a floor whose change was committed just before a crash gets its
version at the next start, and a database from before floors existed gets version 1.
"""

from __future__ import annotations

import builtins
import logging
import threading
from collections.abc import Iterable
from dataclasses import dataclass
from datetime import datetime
from typing import Any

from sqlalchemy import Engine, or_
from sqlmodel import Session, col, func, select

from store.errors import ConflictError, NotFoundError
from store.floors import FloorStore, check_floors, check_unique, map_content, map_hash
from store.history import drop_redo, landmark_record
from store.landmarks import MapRepository
from store.models import (
    AuditRecord,
    Landmark,
    LandmarkCreate,
    LandmarkPublic,
    MapVersion,
    utcnow,
)

log = logging.getLogger(__name__)


@dataclass(frozen=True)
class FloorMap:
    """One floor's map at one version.

    Attributes:
        floor: the floor's ID.
        version: the map's version on that floor (1 is the first).
        hash: sha256 of its content, hex.
        t: when that version was made (UTC).
        actor, action: who made it and how (`key:3`, `update`; `restore`, ...).
        landmarks: its landmarks as JSON records, each with `floor`.
    """

    floor: str
    version: int
    hash: str
    t: datetime
    actor: str
    action: str
    landmarks: tuple[dict[str, Any], ...]


def _records(landmarks: Iterable[LandmarkPublic]) -> builtins.list[dict[str, Any]]:
    return [lm.model_dump(mode="json") for lm in landmarks]


class MapVersions:
    """Versions of each floor's map (thread-safe; reads of the current version are in memory).

    Args:
        engine: the database engine (migrated).
        map: the landmark map (its listeners drive `sync`).
        floors: the site's floors.
    """

    def __init__(self, engine: Engine, map: MapRepository, floors: FloorStore) -> None:
        self.engine, self.map, self.floors = engine, map, floors
        self._lock = threading.Lock()
        self._current: dict[str, tuple[int, str]] = {}
        self.sync()
        map.add_listener(self._on_map_changed)

    def close(self) -> None:
        self.map.remove_listener(self._on_map_changed)

    def _on_map_changed(self, _landmarks: builtins.list[LandmarkPublic]) -> None:
        self.sync()

    # -- following the map -----------------------------------------------------------------
    def sync(self) -> dict[str, int]:
        """Record a new version for every floor whose map differs from its latest version;
        returns {floor: version} of those recorded."""
        made: dict[str, int] = {}
        with self._lock, Session(self.engine) as s:
            audit = s.exec(select(AuditRecord).order_by(col(AuditRecord.id).desc())).first()
            for floor in self.floors.ids():
                records = _records(self.map.on_floor(floor))
                digest = map_hash(records)
                latest = s.exec(
                    select(MapVersion)
                    .where(MapVersion.floor == floor)
                    .order_by(col(MapVersion.version).desc())
                ).first()
                if latest is not None and latest.hash == digest:
                    self._current[floor] = (latest.version, latest.hash)
                    continue
                version = 1 if latest is None else latest.version + 1
                first = latest is None
                s.add(
                    MapVersion(
                        floor=floor,
                        version=version,
                        hash=digest,
                        actor="" if first or audit is None else audit.actor,
                        action="first" if first or audit is None else audit.action,
                        audit_id=None if first or audit is None else audit.id,
                        landmarks=records,
                    )
                )
                made[floor] = version
                self._current[floor] = (version, digest)
            s.commit()
        for floor in set(self._current) - set(self.floors.ids()):
            self._current.pop(floor, None)
        return made

    # -- reads -----------------------------------------------------------------------------
    def current(self, floor: str) -> tuple[int, str]:
        """(version, hash) of the floor's map now; NotFoundError for an unknown floor."""
        found = self._current.get(floor)
        if found is None:
            self.floors.get(floor)  # NotFoundError naming it
            self.sync()
            found = self._current.get(floor, (0, map_hash([])))
        return found

    def version(self, floor: str) -> int:
        """The floor's map version now (0 for a floor the versions do not know yet)."""
        return self._current.get(floor, (0, ""))[0]

    def get(self, floor: str, version: int | None = None) -> FloorMap:
        """The floor's map at `version` (None: now); NotFoundError names an unknown floor
        or version."""
        self.floors.get(floor)
        with Session(self.engine) as s:
            q = select(MapVersion).where(MapVersion.floor == floor)
            if version is None:
                q = q.order_by(col(MapVersion.version).desc())
            else:
                q = q.where(MapVersion.version == version)
            row = s.exec(q).first()
        if row is None:
            newest = self.version(floor)
            raise NotFoundError(
                f"floor {floor!r} has no map version {version} (versions 1-{newest})"
            )
        return FloorMap(
            floor, row.version, row.hash, row.t, row.actor, row.action, tuple(row.landmarks)
        )

    def history(self, floor: str, limit: int = 100) -> builtins.list[FloorMap]:
        """The floor's versions, newest first (their landmarks left out)."""
        self.floors.get(floor)
        with Session(self.engine) as s:
            rows = s.exec(
                select(MapVersion)
                .where(MapVersion.floor == floor)
                .order_by(col(MapVersion.version).desc())
                .limit(limit)
            ).all()
        return [FloorMap(floor, r.version, r.hash, r.t, r.actor, r.action, ()) for r in rows]

    def count(self, floor: str) -> int:
        """How many versions the floor's map has had."""
        with Session(self.engine) as s:
            return int(
                s.exec(
                    select(func.count()).select_from(MapVersion).where(MapVersion.floor == floor)
                ).one()
            )

    # -- writes ----------------------------------------------------------------------------
    def replace_floor(
        self,
        floor: str,
        landmarks: Iterable[LandmarkCreate],
        *,
        actor: str,
        confirm: bool = False,
    ) -> int:
        """Replace one floor's landmarks (the other floors keep theirs): one transaction, one
        undoable step (`floor-import`); returns the count. A landmark that names no floor
        goes on this one; one naming another floor is refused (ConflictError). Emptying the
        floor needs `confirm` (ConflictError)."""
        items = []
        for lm in landmarks:
            if "floor" not in lm.model_fields_set:
                lm = lm.model_copy(update={"floor": floor})
            elif lm.floor != floor:
                raise ConflictError(
                    f"map of floor {floor!r}: landmark {lm.id} names floor {lm.floor!r}"
                )
            items.append(lm)
        self.floors.get(floor)
        now = self.map.on_floor(floor)
        if not items and now and not confirm:
            raise ConflictError(
                f"the new map of floor {floor!r} has no landmarks: it would remove all "
                f"{len(now)}; confirm it (confirm=true)"
            )
        self._write_floor(floor, items, actor=actor, action="floor-import", extra={})
        return len(items)

    def restore(self, floor: str, version: int, *, actor: str, confirm: bool = False) -> FloorMap:
        """Set the floor's map back to an old version's content (the other floors keep
        theirs); audited as `restore` (one undoable step) and recorded as a new version.
        Returns the new current version.

        Raises:
            NotFoundError: an unknown floor or version.
            ConflictError: without `confirm` (it replaces the floor's map: the message says
                how), when the version has the current content, or when a landmark ID or
                radio of that version is used on another floor now.
        """
        old = self.get(floor, version)
        current, digest = self.current(floor)
        if digest == old.hash:
            raise ConflictError(
                f"floor {floor!r}: version {version} has the content of the current version "
                f"{current}: nothing to restore"
            )
        if not confirm:
            raise ConflictError(
                f"restoring floor {floor!r} to version {version} replaces its map "
                f"({len(self.map.on_floor(floor))} landmarks now, {len(old.landmarks)} "
                f"then); confirm it (confirm=true)"
            )
        items = [LandmarkCreate.model_validate({**r, "floor": floor}) for r in old.landmarks]
        self._write_floor(floor, items, actor=actor, action="restore", extra={"version": version})
        return self.get(floor)

    def _write_floor(
        self,
        floor: str,
        items: builtins.list[LandmarkCreate],
        *,
        actor: str,
        action: str,
        extra: dict[str, Any],
    ) -> None:
        """Make `items` the floor's landmarks in one transaction, audited: landmarks kept
        are updated in place (their battery history stays), the others removed or added."""
        what = f"{action} of floor {floor!r}"
        check_unique(items, what=what)
        stamp = utcnow()
        with self.map.write_lock, Session(self.engine) as s:
            check_floors(s, [floor], what=what)
            self._check_free(s, floor, items, what=what)
            rows = {r.id: r for r in s.exec(select(Landmark).where(Landmark.floor == floor))}
            before = [landmark_record(r) for r in sorted(rows.values(), key=lambda r: r.id)]
            wanted = {lm.id: lm for lm in items}
            for lid in set(rows) - set(wanted):
                s.delete(rows.pop(lid))
            for lid, kept in rows.items():  # free the radios that move, before any is taken
                if kept.radio is not None and kept.radio != wanted[lid].radio:
                    kept.radio = None
                    s.add(kept)
            s.flush()
            for lid, lm in wanted.items():
                row = rows.get(lid)
                data = lm.model_dump()
                if row is None:
                    s.add(
                        Landmark.model_validate({**data, "created_at": stamp, "updated_at": stamp})
                    )
                    continue
                if any(getattr(row, k) != v for k, v in data.items()):
                    for k, v in data.items():
                        setattr(row, k, v)
                    row.updated_at = stamp
                    s.add(row)
            s.flush()
            after_rows = s.exec(select(Landmark).where(Landmark.floor == floor)).all()
            after = [landmark_record(r) for r in sorted(after_rows, key=lambda r: r.id)]
            s.add(
                AuditRecord(
                    actor=actor,
                    action=action,
                    before={"floor": floor, "landmarks": before},
                    after={"floor": floor, **extra, "landmarks": after},
                )
            )
            drop_redo(s, actor)
            s.commit()
        self.map.committed()

    @staticmethod
    def _check_free(
        s: Session, floor: str, items: builtins.list[LandmarkCreate], *, what: str
    ) -> None:
        """ConflictError naming a landmark ID or radio that another floor uses."""
        ids = [lm.id for lm in items]
        radios = [lm.radio for lm in items if lm.radio]
        elsewhere = s.exec(
            select(Landmark)
            .where(Landmark.floor != floor)
            .where(or_(col(Landmark.id).in_(ids), col(Landmark.radio).in_(radios)))
        ).first()
        if elsewhere is None:
            return
        if elsewhere.id in ids:
            raise ConflictError(
                f"{what}: landmark {elsewhere.id} hangs on floor {elsewhere.floor!r} "
                "(landmark IDs are unique across the site)"
            )
        mine = next(lm.id for lm in items if lm.radio == elsewhere.radio)
        raise ConflictError(
            f"{what}: radio {elsewhere.radio} of landmark {mine} belongs to landmark "
            f"{elsewhere.id} on floor {elsewhere.floor!r} (radio addresses are unique "
            "across the site)"
        )


__all__ = ["FloorMap", "MapVersions", "map_content"]

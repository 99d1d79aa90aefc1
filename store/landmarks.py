"""The landmark map in the database: CRUD, map import/export (JSON, CSV), audit.

Every change is one transaction committed before the call returns (an acknowledged change is
on disk), writes an audit record (who, when, before/after) and then notifies the listeners
(the live site re-reads the map, the viewer redraws). Undo and redo per author:
`store.history` (`MapRepository.history`). A change that would leave the site without
landmarks (deleting the last one, importing an empty map) needs `confirm=True`.

Reads come from an in-memory snapshot of the table, rebuilt after each change (the server is
the map's only writer; every change, undo and redo included, ends in `_notify`): listing
20,000 landmarks, `/healthz`'s count and the localizer's `LandmarkMap` cost no query. An
import is one multi-row INSERT in one transaction.
"""

from __future__ import annotations

import builtins
import csv
import io
import json
import logging
import math
import threading
from collections.abc import Callable, Iterable
from typing import Any

import numpy as np
from pydantic import ValidationError
from sqlalchemy import Engine, delete, insert
from sqlmodel import Session, col, select

from localizer.landmark_map import LandmarkMap
from store.errors import ConflictError, NotFoundError
from store.floors import check_floors, check_unique, floor_ids
from store.history import MapHistory, drop_redo, landmark_record
from store.models import (
    DECIMAL_ID,
    AuditRecord,
    Landmark,
    LandmarkCreate,
    LandmarkPublic,
    LandmarkUpdate,
    MapDocument,
    utcnow,
)

log = logging.getLogger(__name__)
MapListener = Callable[[list[LandmarkPublic]], None]
CSV_FIELDS = ("id", "x", "y", "z", "radio", "locked", "note", "floor")


def _public(row: Landmark) -> LandmarkPublic:
    return LandmarkPublic.model_validate(row, from_attributes=True)


class MapRepository:
    """The site's landmark map.

    Args:
        engine: the database engine (migrated).
    """

    def __init__(self, engine: Engine) -> None:
        self.engine = engine
        self._listeners: list[MapListener] = []
        self._lock = threading.Lock()  # serialises writers (check-then-write)
        self._revision = 0  # bumped after every committed change
        self._snapshot: tuple[int, builtins.list[LandmarkPublic]] | None = None
        self._map: tuple[int, LandmarkMap] | None = None
        self._floor_maps: dict[str, tuple[int, LandmarkMap]] = {}
        self.history = MapHistory(engine, self._lock, self._notify)
        """Undo and redo of each author's own edits."""
        self.write_lock = self._lock
        """Held by every writer (other writers of the table take it too: floor maps)."""

    # -- listeners ---------------------------------------------------------------------------
    def add_listener(self, listener: MapListener) -> None:
        """Call `listener(all_landmarks)` after every committed change (any thread)."""
        self._listeners.append(listener)

    def remove_listener(self, listener: MapListener) -> None:
        if listener in self._listeners:
            self._listeners.remove(listener)

    def committed(self) -> None:
        """Another writer (holding `write_lock`) committed a change: notify the listeners."""
        self._notify()

    def _notify(self) -> None:
        self._revision += 1
        snapshot = self.list()
        for listener in list(self._listeners):
            try:
                listener(snapshot)
            except Exception:
                log.exception("map listener %r failed", listener)

    # -- reads -------------------------------------------------------------------------------
    def list(self) -> builtins.list[LandmarkPublic]:
        """Every landmark, by ID (a copy of the snapshot)."""
        return builtins.list(self._current())

    def count(self) -> int:
        """How many landmarks the map holds."""
        return len(self._current())

    def _current(self) -> builtins.list[LandmarkPublic]:
        revision, cached = self._revision, self._snapshot
        if cached is not None and cached[0] == revision:
            return cached[1]
        table = Landmark.__table__  # type: ignore[attr-defined]
        with Session(self.engine) as s:
            rows = s.connection().execute(table.select().order_by(table.c.id)).mappings().all()
        # the rows were validated on the way in: no second validation of 20,000 records
        out = [LandmarkPublic.model_construct(**row) for row in rows]
        if self._revision == revision:
            self._snapshot = (revision, out)
        return out

    def get(self, landmark_id: int) -> LandmarkPublic:
        with Session(self.engine) as s:
            row = s.get(Landmark, landmark_id)
            if row is None:
                raise NotFoundError(f"landmark {landmark_id} does not exist")
            return _public(row)

    def on_floor(self, floor: str) -> builtins.list[LandmarkPublic]:
        """The landmarks of one floor, by ID."""
        return [lm for lm in self._current() if lm.floor == floor]

    def landmark_map(self, floor: str | None = None) -> LandmarkMap:
        """The map as the localizer wants it (built once per change of the map): one
        floor's landmarks, or (None) the whole site's."""
        revision = self._revision
        cached = self._map if floor is None else self._floor_maps.get(floor)
        if cached is not None and cached[0] == revision:
            return cached[1]
        lms = self._current() if floor is None else self.on_floor(floor)
        out = LandmarkMap(
            np.array([lm.id for lm in lms], dtype=np.int64),
            np.array([(lm.x, lm.y, lm.z) for lm in lms], dtype=np.float64).reshape(-1, 3),
            None
            if all(lm.sigma_m is None for lm in lms)
            else np.array([math.nan if lm.sigma_m is None else lm.sigma_m for lm in lms]),
        )
        if self._revision == revision:
            if floor is None:
                self._map = (revision, out)
            else:
                self._floor_maps[floor] = (revision, out)
        return out

    def addresses(self) -> dict[int, str]:
        """Landmark ID -> radio address, for the landmarks that have one."""
        return {lm.id: lm.radio for lm in self.list() if lm.radio}

    def audit(self, limit: int = 100, landmark_id: int | None = None) -> builtins.list[AuditRecord]:
        """The newest audit records first."""
        with Session(self.engine) as s:
            q = select(AuditRecord).order_by(col(AuditRecord.id).desc()).limit(limit)
            if landmark_id is not None:
                q = q.where(AuditRecord.landmark_id == landmark_id)
            return list(s.exec(q))

    # -- writes ------------------------------------------------------------------------------
    def _check_radio_free(self, s: Session, radio: str | None, landmark_id: int) -> None:
        if radio is None:
            return
        other = s.exec(select(Landmark).where(Landmark.radio == radio)).first()
        if other is not None and other.id != landmark_id:
            raise ConflictError(f"radio {radio} already belongs to landmark {other.id}")

    def create(self, data: LandmarkCreate, *, actor: str) -> LandmarkPublic:
        """Add a landmark; ConflictError on a taken ID or radio address."""
        with self._lock, Session(self.engine) as s:
            if s.get(Landmark, data.id) is not None:
                raise ConflictError(f"landmark {data.id} already exists")
            check_floors(s, [data.floor], what=f"landmark {data.id}")
            self._check_radio_free(s, data.radio, data.id)
            row = Landmark.model_validate(data.model_dump())
            s.add(row)
            s.add(
                AuditRecord(
                    actor=actor, action="create", landmark_id=data.id, after=landmark_record(row)
                )
            )
            drop_redo(s, actor)
            s.commit()
            s.refresh(row)
            out = _public(row)
        self._notify()
        return out

    def update(self, landmark_id: int, data: LandmarkUpdate, *, actor: str) -> LandmarkPublic:
        """Change the fields set in `data` (`radio: null` clears the address)."""
        return self.update_many([(landmark_id, data)], actor=actor)[0]

    def update_many(
        self, edits: builtins.list[tuple[int, LandmarkUpdate]], *, actor: str
    ) -> builtins.list[LandmarkPublic]:
        """`update` of several landmarks in one transaction: all are written or none (a
        crash midway leaves the map as it was); each stays its own audited, undoable edit."""
        for _, data in edits:
            changes = data.model_dump(exclude_unset=True)
            for key in ("x", "y", "z", "locked"):
                if key in changes and changes[key] is None:
                    raise ValueError(f"{key} cannot be null")
        rows = []
        with self._lock, Session(self.engine) as s:
            for landmark_id, data in edits:
                changes = data.model_dump(exclude_unset=True)
                row = s.get(Landmark, landmark_id)
                if row is None:
                    raise NotFoundError(f"landmark {landmark_id} does not exist")
                before = landmark_record(row)
                if "radio" in changes:
                    self._check_radio_free(s, changes["radio"], landmark_id)
                if "floor" in changes:
                    check_floors(s, [changes["floor"]], what=f"landmark {landmark_id}")
                moved = any(
                    key in changes and changes[key] != getattr(row, key) for key in ("x", "y", "z")
                )
                if moved and "sigma_m" not in changes:  # a hand edit: the old uncertainty is void
                    changes.update(sigma_m=None, covariance=None, evidence=None)
                for key, value in changes.items():
                    setattr(row, key, value if key != "note" or value is not None else "")
                row.updated_at = utcnow()
                s.add(row)
                s.add(
                    AuditRecord(
                        actor=actor,
                        action="update",
                        landmark_id=landmark_id,
                        before=before,
                        after=landmark_record(row),
                    )
                )
                rows.append(row)
            drop_redo(s, actor)
            s.commit()
            out = []
            for row in rows:
                s.refresh(row)
                out.append(_public(row))
        self._notify()
        return out

    def delete(self, landmark_id: int, *, actor: str, confirm: bool = False) -> None:
        """Remove a landmark; the last one of the map only with `confirm` (ConflictError)."""
        with self._lock, Session(self.engine) as s:
            row = s.get(Landmark, landmark_id)
            if row is None:
                raise NotFoundError(f"landmark {landmark_id} does not exist")
            if not confirm and len(s.exec(select(Landmark.id)).all()) == 1:
                raise ConflictError(
                    f"landmark {landmark_id} is the last landmark of the map: deleting it "
                    "leaves the site without landmarks; confirm it (confirm=true)"
                )
            s.add(
                AuditRecord(
                    actor=actor,
                    action="delete",
                    landmark_id=landmark_id,
                    before=landmark_record(row),
                )
            )
            s.delete(row)
            drop_redo(s, actor)
            s.commit()
        self._notify()

    def replace_all(
        self, landmarks: Iterable[LandmarkCreate], *, actor: str, confirm: bool = False
    ) -> int:
        """Replace the whole map in one transaction (map import; with no landmarks: clear,
        which needs `confirm` when the map has any); returns the count. One undoable step.
        (One floor's map: `store.map_versions.MapVersions.replace_floor`.)

        Raises:
            ConflictError: a duplicate ID or radio address in the new map, or a clear without
                `confirm` (nothing changes).
            UnknownFloorError: a landmark on a floor the site does not have (nothing changes).
        """
        items = list(landmarks)
        check_unique(items, what="map")
        now = utcnow()
        rows = [{**lm.model_dump(), "created_at": now, "updated_at": now} for lm in items]
        with self._lock, Session(self.engine) as s:
            known = set(floor_ids(s))
            for lm in items:
                if lm.floor not in known:
                    check_floors(s, [lm.floor], what=f"map: landmark {lm.id}")  # raises
            # the snapshot's records are `landmark_record`'s (LandmarkPublic as JSON)
            before = {"landmarks": [lm.model_dump(mode="json") for lm in self._current()]}
            if not items and before["landmarks"] and not confirm:
                raise ConflictError(
                    f"the new map has no landmarks: it would remove all "
                    f"{len(before['landmarks'])} and leave the site without landmarks; "
                    "confirm it (confirm=true, or allow_empty=true)"
                )
            s.exec(delete(Landmark))
            if rows:
                s.connection().execute(insert(Landmark.__table__), rows)  # type: ignore[attr-defined]
            stamp = now.isoformat()
            after = {"landmarks": [{**r, "created_at": stamp, "updated_at": stamp} for r in rows]}
            action = "import" if items else "clear"
            s.add(AuditRecord(actor=actor, action=action, before=before, after=after))
            drop_redo(s, actor)
            s.commit()
        self._notify()
        return len(items)

    # -- map documents ---------------------------------------------------------------------
    def export_json(self) -> dict[str, Any]:
        """map.json of the recording format, with `radio`, `locked` and `note` kept."""
        return {
            "landmarks": [
                lm.model_dump(mode="json", exclude={"created_at", "updated_at"})
                for lm in self.list()
            ]
        }

    def export_csv(self) -> str:
        out = io.StringIO()
        writer = csv.DictWriter(out, fieldnames=CSV_FIELDS, lineterminator="\n")
        writer.writeheader()
        for lm in self.list():
            writer.writerow(
                {k: getattr(lm, k) if getattr(lm, k) is not None else "" for k in CSV_FIELDS}
            )
        return out.getvalue()


def parse_map_json(data: Any, *, source: str = "map.json") -> builtins.list[LandmarkCreate]:
    """Validate a map document; ValueError names the landmark and field."""
    try:
        return MapDocument.model_validate(data).landmarks
    except ValidationError as exc:
        raise ValueError(f"{source}: {_first_error(exc)}") from None
    except RecursionError:
        raise ValueError(f"{source}: JSON nested too deeply") from None


def parse_map_text(text: str, *, source: str = "map.json") -> builtins.list[LandmarkCreate]:
    """Parse and validate map.json text; ValueError says what is wrong (not JSON, nested
    too deeply, a bad landmark)."""
    try:
        data = json.loads(text)
    except json.JSONDecodeError as exc:
        raise ValueError(f"{source}: body is not JSON: {exc}") from None
    except RecursionError:
        raise ValueError(f"{source}: JSON nested too deeply (more than ~900 levels)") from None
    return parse_map_json(data, source=source)


def decode_text(raw: bytes, *, source: str) -> str:
    """UTF-8 text of an uploaded document, a leading byte-order mark (as spreadsheet
    programs write it) dropped; ValueError for bytes that are not UTF-8."""
    try:
        return raw.decode("utf-8-sig")
    except UnicodeDecodeError as exc:
        raise ValueError(
            f"{source}: body is not UTF-8 text (byte {exc.start} is {raw[exc.start]:#04x})"
        ) from None


def parse_map_csv(text: str, *, source: str = "map.csv") -> builtins.list[LandmarkCreate]:
    """Parse the CSV export (`id,x,y,z,radio,locked,note,floor`; radio, locked, note,
    floor optional).

    A leading byte-order mark is skipped. Raises ValueError naming the line and what is
    wrong: an unknown column, a row with more fields than the header, a field over
    `csv.field_size_limit()` characters, a line break inside an unquoted field, an ID that
    is not a plain decimal integer, a bad value.
    """
    reader = csv.reader(io.StringIO(text.removeprefix("\ufeff")))
    try:
        header = next(reader, None)
        if header is None or not {"id", "x", "y", "z"} <= set(header):
            raise ValueError(f"{source}: header must name at least id,x,y,z")
        unknown = [h for h in header if h not in CSV_FIELDS]
        if unknown:
            raise ValueError(
                f"{source}: header: unknown column {unknown[0]!r} "
                f"(the columns are {','.join(CSV_FIELDS)})"
            )
        items = []
        for fields in reader:
            line = reader.line_num
            if not fields:
                continue
            if len(fields) > len(header):
                raise ValueError(
                    f"{source} line {line}: {len(fields)} fields, the header names "
                    f"{len(header)} ({','.join(header)}): quote a value that holds a comma"
                )
            rec: dict[str, Any] = {k: v for k, v in zip(header, fields, strict=False) if v != ""}
            if "id" in rec:
                rec["id"] = _strict_id(rec["id"], f"{source} line {line}: id")
            for key in ("x", "y", "z"):
                if key in rec:
                    rec[key] = _number(rec[key], f"{source} line {line}: {key}")
            if "locked" in rec:
                rec["locked"] = str(rec["locked"]).strip().lower() in ("1", "true", "yes")
            try:
                items.append(LandmarkCreate.model_validate(rec))
            except ValidationError as exc:
                raise ValueError(f"{source} line {line}: {_first_error(exc)}") from None
    except csv.Error as exc:
        raise ValueError(f"{source} line {reader.line_num}: {_csv_problem(exc)}") from None
    return items


def _strict_id(text: str, where: str) -> int:
    if not DECIMAL_ID.fullmatch(text):
        raise ValueError(f"{where}: expected a plain decimal integer, got {text!r}")
    return int(text)


def _number(text: str, where: str) -> float:
    try:
        return float(text)
    except ValueError:
        raise ValueError(f"{where}: expected a number of metres, got {text!r}") from None


def _csv_problem(exc: csv.Error) -> str:
    text = str(exc)
    if "field limit" in text:
        return f"a field is longer than {csv.field_size_limit()} characters"
    if "new-line" in text:
        return "a line break (CR or LF) inside an unquoted field: quote the field"
    return text


def _first_error(exc: ValidationError) -> str:
    err = exc.errors()[0]
    where = ".".join(str(p) for p in err["loc"])
    return f"{where}: {err['msg']}"

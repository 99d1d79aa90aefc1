"""The landmark map in the database: CRUD, map import/export (JSON, CSV), audit.

Every change is one transaction committed before the call returns (an acknowledged change is
on disk), writes an audit record (who, when, before/after) and then notifies the listeners
(the live site re-reads the map, the viewer redraws). Undo and redo per author:
`server.crud.history` (`MapRepository.history`). A change that would leave the site without
landmarks (deleting the last one, importing an empty map) needs `confirm=True`.
"""

from __future__ import annotations

import builtins
import csv
import io
import logging
import threading
from collections.abc import Callable, Iterable
from typing import Any

from pydantic import ValidationError
from sqlalchemy import Engine, delete
from sqlmodel import Session, col, select

from localizer.landmark_map import LandmarkMap
from server.crud.history import MapHistory, drop_redo, landmark_record
from server.errors import ConflictError, NotFoundError
from server.models import (
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
CSV_FIELDS = ("id", "x", "y", "z", "radio", "locked", "note")


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
        self.history = MapHistory(engine, self._lock, self._notify)
        """Undo and redo of each author's own edits."""

    # -- listeners ---------------------------------------------------------------------------
    def add_listener(self, listener: MapListener) -> None:
        """Call `listener(all_landmarks)` after every committed change (any thread)."""
        self._listeners.append(listener)

    def remove_listener(self, listener: MapListener) -> None:
        if listener in self._listeners:
            self._listeners.remove(listener)

    def _notify(self) -> None:
        snapshot = self.list()
        for listener in list(self._listeners):
            try:
                listener(snapshot)
            except Exception:
                log.exception("map listener %r failed", listener)

    # -- reads -------------------------------------------------------------------------------
    def list(self) -> builtins.list[LandmarkPublic]:
        """Every landmark, by ID."""
        with Session(self.engine) as s:
            return [_public(r) for r in s.exec(select(Landmark).order_by(col(Landmark.id)))]

    def get(self, landmark_id: int) -> LandmarkPublic:
        with Session(self.engine) as s:
            row = s.get(Landmark, landmark_id)
            if row is None:
                raise NotFoundError(f"landmark {landmark_id} does not exist")
            return _public(row)

    def landmark_map(self) -> LandmarkMap:
        """The map as the localizer wants it."""
        return LandmarkMap.from_records([lm.model_dump() for lm in self.list()])

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
        changes = data.model_dump(exclude_unset=True)
        for key in ("x", "y", "z", "locked"):
            if key in changes and changes[key] is None:
                raise ValueError(f"{key} cannot be null")
        with self._lock, Session(self.engine) as s:
            row = s.get(Landmark, landmark_id)
            if row is None:
                raise NotFoundError(f"landmark {landmark_id} does not exist")
            before = landmark_record(row)
            if "radio" in changes:
                self._check_radio_free(s, changes["radio"], landmark_id)
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
            drop_redo(s, actor)
            s.commit()
            s.refresh(row)
            out = _public(row)
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

        Raises:
            ConflictError: a duplicate ID or radio address in the new map, or a clear without
                `confirm` (nothing changes).
        """
        items = list(landmarks)
        ids: set[int] = set()
        radios: dict[str, int] = {}
        for lm in items:
            if lm.id in ids:
                raise ConflictError(f"map: duplicate landmark id {lm.id}")
            ids.add(lm.id)
            if lm.radio is not None:
                if lm.radio in radios:
                    raise ConflictError(
                        f"map: landmarks {radios[lm.radio]} and {lm.id} share radio {lm.radio}"
                    )
                radios[lm.radio] = lm.id
        with self._lock, Session(self.engine) as s:
            before = {"landmarks": [landmark_record(r) for r in s.exec(select(Landmark))]}
            if not items and before["landmarks"] and not confirm:
                raise ConflictError(
                    f"the new map has no landmarks: it would remove all "
                    f"{len(before['landmarks'])} and leave the site without landmarks; "
                    "confirm it (confirm=true)"
                )
            s.exec(delete(Landmark))
            s.flush()
            rows = [Landmark.model_validate(lm.model_dump()) for lm in items]
            s.add_all(rows)
            s.flush()
            after = {"landmarks": [landmark_record(r) for r in rows]}
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


def parse_map_csv(text: str, *, source: str = "map.csv") -> builtins.list[LandmarkCreate]:
    """Parse the CSV export (`id,x,y,z,radio,locked,note`; radio, locked, note optional)."""
    reader = csv.DictReader(io.StringIO(text))
    if reader.fieldnames is None or not {"id", "x", "y", "z"} <= set(reader.fieldnames):
        raise ValueError(f"{source}: header must name at least id,x,y,z")
    items = []
    for line, row in enumerate(reader, start=2):
        rec: dict[str, Any] = {k: v for k, v in row.items() if k in CSV_FIELDS and v != ""}
        if "locked" in rec:
            rec["locked"] = str(rec["locked"]).strip().lower() in ("1", "true", "yes")
        try:
            items.append(LandmarkCreate.model_validate(rec))
        except ValidationError as exc:
            raise ValueError(f"{source} line {line}: {_first_error(exc)}") from None
    return items


def _first_error(exc: ValidationError) -> str:
    err = exc.errors()[0]
    where = ".".join(str(p) for p in err["loc"])
    return f"{where}: {err['msg']}"

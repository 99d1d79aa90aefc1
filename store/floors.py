"""The site's floors in the database: list, create, change, delete, and the checks the
landmark map makes against them (a landmark on a floor that does not exist is refused).

A floor is a storey of the building with its own landmark map (its own map frame: x, y on
that floor, z up from its floor). Landmark IDs and radio addresses stay unique across the
site: one radio network spans every floor.
"""

from __future__ import annotations

import builtins
import hashlib
import json
from collections.abc import Iterable
from typing import Any

from sqlalchemy import Engine
from sqlmodel import Session, col, func, select

from store.errors import ConflictError, NotFoundError
from store.models import DEFAULT_FLOOR, Floor, FloorCreate, FloorUpdate, Landmark, LandmarkCreate

HASHED_OUT = frozenset({"created_at", "updated_at", "floor"})
"""Landmark fields left out of a map's content hash (stamps, and the floor it is the map of)."""


class UnknownFloorError(NotFoundError):
    """A landmark or robot names a floor the site does not have (HTTP 404 naming it; a
    schema-valid request about something that is not there)."""


def map_content(records: Iterable[dict[str, Any]]) -> builtins.list[dict[str, Any]]:
    """A floor's landmarks as its content: the records without stamps or floor, by ID."""
    out = [{k: v for k, v in r.items() if k not in HASHED_OUT} for r in records]
    return sorted(out, key=lambda r: int(r["id"]))


def map_hash(records: Iterable[dict[str, Any]]) -> str:
    """sha256 (hex) of a floor's map content: canonical JSON of `map_content(records)`
    (keys sorted, no spaces; floats as Python writes them, which round-trips exactly)."""
    text = json.dumps(map_content(records), sort_keys=True, separators=(",", ":"))
    return hashlib.sha256(text.encode("utf-8")).hexdigest()


def floor_ids(s: Session) -> builtins.list[str]:
    """Every floor's ID, ordered by level then ID."""
    return [f.id for f in s.exec(select(Floor).order_by(col(Floor.level), col(Floor.id))).all()]


def check_floors(s: Session, floors: Iterable[str], *, what: str) -> None:
    """UnknownFloorError naming the first floor in `floors` the site does not have."""
    known = set(floor_ids(s))
    for floor in floors:
        if floor not in known:
            raise UnknownFloorError(
                f"{what}: floor {floor!r} does not exist (floors: {', '.join(sorted(known))})"
            )


def check_unique(items: Iterable[LandmarkCreate], *, what: str) -> None:
    """ConflictError naming a landmark ID or radio address given twice in `items`."""
    ids: set[int] = set()
    radios: dict[str, int] = {}
    for lm in items:
        if lm.id in ids:
            raise ConflictError(f"{what}: duplicate landmark id {lm.id}")
        ids.add(lm.id)
        if lm.radio is not None:
            if lm.radio in radios:
                raise ConflictError(
                    f"{what}: landmarks {radios[lm.radio]} and {lm.id} share radio {lm.radio}"
                )
            radios[lm.radio] = lm.id


class FloorStore:
    """The floors of the site (each with a name, a level and a height)."""

    def __init__(self, engine: Engine) -> None:
        self.engine = engine

    def list(self) -> builtins.list[Floor]:
        """Every floor, lowest level first."""
        with Session(self.engine) as s:
            return builtins.list(
                s.exec(select(Floor).order_by(col(Floor.level), col(Floor.id))).all()
            )

    def ids(self) -> builtins.list[str]:
        with Session(self.engine) as s:
            return floor_ids(s)

    def get(self, floor_id: str) -> Floor:
        with Session(self.engine) as s:
            row = s.get(Floor, floor_id)
            if row is None:
                raise NotFoundError(f"floor {floor_id!r} does not exist")
            return row

    def check(self, floor_id: str, *, what: str) -> None:
        """UnknownFloorError naming `floor_id` when the site has no such floor."""
        with Session(self.engine) as s:
            check_floors(s, [floor_id], what=what)

    def default(self) -> str:
        """The floor a robot starts on when nothing says otherwise: "0" when the site has
        it, else the lowest level at or above 0, else the lowest."""
        floors = self.list()
        if not floors:
            return DEFAULT_FLOOR
        if any(f.id == DEFAULT_FLOOR for f in floors):
            return DEFAULT_FLOOR
        above = [f for f in floors if f.level >= 0]
        return (above or floors)[0].id

    def create(self, data: FloorCreate) -> Floor:
        """Add a floor; ConflictError when the ID is taken."""
        with Session(self.engine) as s:
            if s.get(Floor, data.id) is not None:
                raise ConflictError(f"floor {data.id!r} already exists")
            row = Floor.model_validate(data.model_dump())
            s.add(row)
            s.commit()
            s.refresh(row)
            return row

    def update(self, floor_id: str, data: FloorUpdate) -> Floor:
        """Change the fields set in `data`."""
        changes = data.model_dump(exclude_unset=True)
        with Session(self.engine) as s:
            row = s.get(Floor, floor_id)
            if row is None:
                raise NotFoundError(f"floor {floor_id!r} does not exist")
            for key, value in changes.items():
                if value is None:
                    raise ValueError(f"{key} cannot be null (leave it out to keep it)")
                setattr(row, key, value)
            s.add(row)
            s.commit()
            s.refresh(row)
            return row

    def delete(self, floor_id: str) -> None:
        """Remove an empty floor; ConflictError while landmarks hang on it or when it is
        the site's last floor."""
        with Session(self.engine) as s:
            row = s.get(Floor, floor_id)
            if row is None:
                raise NotFoundError(f"floor {floor_id!r} does not exist")
            count = int(
                s.exec(
                    select(func.count()).select_from(Landmark).where(Landmark.floor == floor_id)
                ).one()
            )
            if count:
                raise ConflictError(
                    f"floor {floor_id!r} still has {count} landmarks: move or delete them first"
                )
            if len(floor_ids(s)) == 1:
                raise ConflictError(f"floor {floor_id!r} is the site's last floor")
            s.delete(row)
            s.commit()

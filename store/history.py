"""Undo and redo of map edits, per author, on the audit log.

Each author (an API key: the API acts as `key:3`, the viewer as `web:key:3`, one author)
undoes and redoes only their own edits, newest first, as in an editor: an undo reverts one
edit (a landmark's add, change or delete, or a whole-map import or clear), a redo reapplies
the edit undone last, and a new edit by the same author drops what they could still redo.
Edits made by the server itself (the start-up map import, `virtual site`) belong to no key
and cannot be undone from the API or the viewer.

Safety: an undo or redo that changes the whole map, or that would leave the site without
landmarks, needs `confirm=True` (`ConfirmationRequiredError`, HTTP 409, naming what it would do);
one whose landmark (or map) was changed since by anyone is refused (`ConflictError`), so that
an undo never silently overwrites another person's later edit.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from typing import Any, Literal

from sqlalchemy import Engine, delete, update
from sqlmodel import Session, col, func, select

from store.errors import ConflictError
from store.floors import check_floors
from store.models import DEFAULT_FLOOR, AuditRecord, Landmark, LandmarkPublic

EDIT_ACTIONS = ("create", "update", "delete", "import", "clear", "floor-import", "restore")
WHOLE_MAP_ACTIONS = ("import", "clear", "floor-import", "restore")
"""`floor-import` (one floor's map replaced) and `restore` (one floor's map set back to an
old version, `store.map_versions`) are whole-map steps: their records hold the site's
map before and after, plus `floor` (and `version`, for a restore)."""
VIEWER_PREFIX = "web:"
"""How the viewer (the web app) names its users' edits: `web:key:3`."""
OLD_VIEWER_PREFIX = "viewer:"
"""... as it did before (it read like the viewer role for an admin's edits): still theirs."""
_STAMPS = ("created_at", "updated_at")


def landmark_record(row: Landmark) -> dict[str, Any]:
    """A landmark row as the audit log stores it (JSON-ready)."""
    return LandmarkPublic.model_validate(row, from_attributes=True).model_dump(mode="json")


def landmark_from_record(rec: dict[str, Any]) -> Landmark:
    """The row an audit record describes (timestamps parsed back)."""
    out = dict(rec)
    for key in _STAMPS:
        if isinstance(out.get(key), str):
            out[key] = datetime.fromisoformat(out[key])
    return Landmark.model_validate(out)


SOURCES = (" (survey)", " (map upkeep)")
"""Suffixes naming what a user's edit came from (`key:3 (survey)`: key 3 accepted a survey's
proposal); the edit is still theirs to undo."""


def owner_of(actor: str) -> str:
    """The author behind an audit actor: `web:key:3`, `key:3` and `key:3 (survey)` are
    the same key."""
    owner = actor.removeprefix(VIEWER_PREFIX).removeprefix(OLD_VIEWER_PREFIX)
    for suffix in SOURCES:
        owner = owner.removesuffix(suffix)
    return owner


def _actors(owner: str) -> list[str]:
    plain = [owner, VIEWER_PREFIX + owner, OLD_VIEWER_PREFIX + owner]
    return plain + [a + suffix for a in plain for suffix in SOURCES]


_NO_UNCERTAINTY: dict[str, Any] = {"sigma_m": None, "covariance": None, "evidence": None}


def _content(rec: dict[str, Any] | None) -> dict[str, Any] | None:
    if rec is None:
        return None
    # records written before floors existed name none: their landmarks are on floor "0";
    # before uncertainties were kept, none was known
    return {"floor": DEFAULT_FLOOR, **_NO_UNCERTAINTY} | {
        k: v for k, v in rec.items() if k not in _STAMPS
    }


def _map_of(rec: dict[str, Any] | None) -> dict[int, dict[str, Any] | None]:
    return {int(r["id"]): _content(r) for r in (rec or {}).get("landmarks", [])}


def _n(count: int) -> str:
    return f"{count} landmark" + ("" if count == 1 else "s")


def describe(action: str, landmark_id: int | None, before: Any, after: Any) -> str:
    """What an edit did, for people: "move of landmark 17", "map import (39 landmarks)"."""
    if action == "import":
        n_before, n_after = len(_map_of(before)), len(_map_of(after))
        return f"map import ({n_before} -> {_n(n_after)})"
    if action == "floor-import":
        floor = (after or {}).get("floor")
        n_floor = sum(1 for r in (after or {}).get("landmarks", []) if r.get("floor") == floor)
        return f"map import of floor {floor} ({_n(n_floor)})"
    if action == "restore":
        a = after or {}
        return f"map restore of floor {a.get('floor')} to version {a.get('version')}"
    if action == "clear":
        return f"map clear ({_n(len(_map_of(before)))} removed)"
    what = {"create": "add", "delete": "delete"}.get(action)
    if what is None:
        b, a = before or {}, after or {}
        changed = [k for k in ("x", "y", "z", "locked", "radio", "note") if b.get(k) != a.get(k)]
        if "x" in changed or "y" in changed:
            what = "move"
        elif "z" in changed:
            what = "height change"
        elif "locked" in changed:
            what = "lock" if a.get("locked") else "unlock"
        elif "radio" in changed:
            what = "radio change"
        elif "note" in changed:
            what = "note change"
        else:
            what = "edit"
    return f"{what} of landmark {landmark_id}"


@dataclass(frozen=True)
class MapStep:
    """One edit that an undo or redo would act on.

    Attributes:
        record_id: the edit's audit record.
        action: create, update, delete, import or clear.
        landmark_id: the landmark edited (None for whole-map edits).
        description: what the edit did ("move of landmark 17").
        t: when the edit was made (UTC).
        direction: what acting on it does: "undo" reverts it, "redo" reapplies it.
        landmarks_now: landmarks in the map now.
        landmarks_after: landmarks in the map after acting on it.
    """

    record_id: int
    action: str
    landmark_id: int | None
    description: str
    t: datetime
    direction: Literal["undo", "redo"]
    landmarks_now: int
    landmarks_after: int

    @property
    def whole_map(self) -> bool:
        return self.action in WHOLE_MAP_ACTIONS

    @property
    def needs_confirmation(self) -> bool:
        """A whole-map step, or one that would leave the site without landmarks."""
        return self.whole_map or (self.landmarks_after == 0 and self.landmarks_now > 0)

    @property
    def title(self) -> str:
        """ "undo move of landmark 17"."""
        return f"{self.direction} {self.description}"


class ConfirmationRequiredError(ConflictError):
    """The step changes the whole map or empties it: repeat with confirmation (HTTP 409)."""

    def __init__(self, step: MapStep) -> None:
        self.step = step
        after = "no landmarks" if step.landmarks_after == 0 else f"{step.landmarks_after}"
        super().__init__(
            f"{step.title} would change the whole map ({step.landmarks_now} landmarks -> "
            f"{after}): confirm it (confirm=true)"
            if step.whole_map
            else f"{step.title} would leave the site without landmarks: confirm it (confirm=true)"
        )


class MapHistory:
    """Undo and redo on a `MapRepository`'s database (shares its writer lock).

    Args:
        engine: the database engine.
        lock: the repository's writer lock.
        notify: called after a committed undo or redo (the repository's listeners).
    """

    def __init__(self, engine: Engine, lock: threading.Lock, notify: Callable[[], None]) -> None:
        self.engine, self._lock, self._notify = engine, lock, notify

    # -- what would happen -------------------------------------------------------------------
    def next_undo(self, actor: str) -> MapStep | None:
        """The edit `actor`'s next undo reverts (their newest edit in effect), or None."""
        with Session(self.engine) as s:
            rec = self._undoable(s, owner_of(actor))
            return None if rec is None else self._step(s, rec, "undo")

    def next_redo(self, actor: str) -> MapStep | None:
        """The edit `actor`'s next redo reapplies (the one they undid last), or None."""
        with Session(self.engine) as s:
            rec = self._redoable(s, owner_of(actor))
            return None if rec is None else self._step(s, rec, "redo")

    def _undoable(self, s: Session, owner: str) -> AuditRecord | None:
        return s.exec(
            select(AuditRecord)
            .where(col(AuditRecord.actor).in_(_actors(owner)))
            .where(col(AuditRecord.action).in_(EDIT_ACTIONS))
            .where(AuditRecord.undo_state == "")
            .order_by(col(AuditRecord.id).desc())
        ).first()

    def _redoable(self, s: Session, owner: str) -> AuditRecord | None:
        # undos go newest first, so the edit undone last is the oldest one still undone
        return s.exec(
            select(AuditRecord)
            .where(col(AuditRecord.actor).in_(_actors(owner)))
            .where(col(AuditRecord.action).in_(EDIT_ACTIONS))
            .where(AuditRecord.undo_state == "undone")
            .order_by(col(AuditRecord.id))
        ).first()

    def _step(self, s: Session, rec: AuditRecord, direction: Literal["undo", "redo"]) -> MapStep:
        now = int(s.exec(select(func.count()).select_from(Landmark)).one())
        target = rec.before if direction == "undo" else rec.after
        source = rec.after if direction == "undo" else rec.before
        if rec.action in WHOLE_MAP_ACTIONS:  # the whole site's map, or one floor's
            after = now - len(_map_of(source)) + len(_map_of(target))
        else:
            after = now + (target is not None) - (source is not None)
        return MapStep(
            record_id=rec.id or 0,
            action=rec.action,
            landmark_id=rec.landmark_id,
            description=describe(rec.action, rec.landmark_id, rec.before, rec.after),
            t=rec.t,
            direction=direction,
            landmarks_now=now,
            landmarks_after=after,
        )

    # -- acting ------------------------------------------------------------------------------
    def undo(self, actor: str, *, confirm: bool = False, expect: int | None = None) -> MapStep:
        """Revert `actor`'s newest edit in effect; returns what was undone.

        Args:
            actor: who asks (only their own edits are undone).
            confirm: the user confirmed a whole-map step or one emptying the map.
            expect: the `record_id` of the step the user was shown; refused when the next
                step is another one by now.

        Raises:
            ConflictError: nothing to undo, not the step expected, or the landmark/map
                changed since the edit.
            ConfirmationRequiredError: a whole-map step, or one emptying the map, without
                `confirm`.
        """
        return self._act(actor, "undo", confirm=confirm, expect=expect)

    def redo(self, actor: str, *, confirm: bool = False, expect: int | None = None) -> MapStep:
        """Reapply the edit `actor` undid last (arguments and errors as `undo`)."""
        return self._act(actor, "redo", confirm=confirm, expect=expect)

    def _act(
        self,
        actor: str,
        direction: Literal["undo", "redo"],
        *,
        confirm: bool,
        expect: int | None,
    ) -> MapStep:
        owner = owner_of(actor)
        with self._lock, Session(self.engine) as s:
            rec = self._undoable(s, owner) if direction == "undo" else self._redoable(s, owner)
            if rec is None:
                raise ConflictError(f"nothing of yours ({owner}) to {direction}")
            step = self._step(s, rec, direction)
            if expect is not None and rec.id != expect:
                raise ConflictError(
                    f"your next {direction} is now {step.description}: nothing changed, look again"
                )
            if step.needs_confirmation and not confirm:
                raise ConfirmationRequiredError(step)
            source = rec.after if direction == "undo" else rec.before
            target = rec.before if direction == "undo" else rec.after
            if rec.action in WHOLE_MAP_ACTIONS:
                self._set_map(s, step, source, target)
            else:
                self._set_landmark(s, step, source, target)
            s.add(
                AuditRecord(
                    actor=actor,
                    action=direction,
                    landmark_id=rec.landmark_id,
                    before=source,
                    after=target,
                    target_id=rec.id,
                )
            )
            rec.undo_state = "undone" if direction == "undo" else ""
            s.add(rec)
            s.commit()
        self._notify()
        return step

    def _set_landmark(
        self, s: Session, step: MapStep, source: Any, target: dict[str, Any] | None
    ) -> None:
        lid = step.landmark_id
        row = s.get(Landmark, lid)
        current = None if row is None else landmark_record(row)
        if _content(current) != _content(source):
            raise ConflictError(
                f"landmark {lid} has changed since the edit: {step.title} refused (nothing changed)"
            )
        if target is not None and target.get("radio"):
            other = s.exec(select(Landmark).where(Landmark.radio == target["radio"])).first()
            if other is not None and other.id != lid:
                raise ConflictError(
                    f"{step.title} refused: radio {target['radio']} now belongs to landmark "
                    f"{other.id}"
                )
        if target is not None:
            check_floors(s, [target.get("floor", DEFAULT_FLOOR)], what=step.title)
        if row is not None:
            s.delete(row)
            s.flush()
        if target is not None:
            s.add(landmark_from_record(target))

    def _set_map(self, s: Session, step: MapStep, source: Any, target: Any) -> None:
        floor = (source or {}).get("floor")  # a floor's import or restore: only that floor
        rows = (
            select(Landmark) if floor is None else select(Landmark).where(Landmark.floor == floor)
        )
        current = {lm.id: _content(landmark_record(lm)) for lm in s.exec(rows)}
        if current != _map_of(source):
            raise ConflictError(
                f"the map has changed since the {step.description}: {step.title} refused "
                "(nothing changed)"
            )
        records = (target or {}).get("landmarks", [])
        if floor is not None:
            taken = s.exec(
                select(Landmark.id)
                .where(col(Landmark.id).in_([int(r["id"]) for r in records]))
                .where(Landmark.floor != floor)
            ).first()
            if taken is not None:
                raise ConflictError(
                    f"{step.title} refused: landmark {taken} now hangs on another floor"
                )
            check_floors(s, [floor], what=step.title)
        s.exec(
            delete(Landmark)
            if floor is None
            else delete(Landmark).where(col(Landmark.floor) == floor)
        )
        s.flush()
        for rec in records:
            s.add(landmark_from_record(rec))


def drop_redo(s: Session, actor: str) -> None:
    """A new edit by `actor`: what they undid can no longer be redone (call in its
    transaction)."""
    s.exec(
        update(AuditRecord)
        .where(col(AuditRecord.actor).in_(_actors(owner_of(actor))))
        .where(col(AuditRecord.undo_state) == "undone")
        .values(undo_state="dropped")
    )

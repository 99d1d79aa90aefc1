"""`/map/history`, `/map/undo`, `/map/redo`: each key undoes and redoes its own map edits.

The viewer's Undo and Redo buttons are these same actions (`store.history`).
"""

from __future__ import annotations

import asyncio
from datetime import datetime
from typing import Literal

from fastapi import APIRouter, Query
from pydantic import BaseModel, Field

from server.auth import Admin
from server.deps import ServicesDep
from store.history import MapStep

router = APIRouter(prefix="/map", tags=["map"])
Confirm = Query(
    False,
    description="required for a step that changes the whole map (an import or clear) or "
    "leaves the site without landmarks; without it such a step answers 409",
)


class StepPublic(BaseModel):
    """One edit an undo or redo acts on."""

    record_id: int = Field(description="the edit's audit record (`/landmarks/audit`)")
    action: str = Field(description="create, update, delete, import or clear")
    landmark_id: int | None = Field(description="the landmark edited; null for a whole map")
    title: str = Field(description='what acting does, e.g. "undo move of landmark 17"')
    t: datetime = Field(description="when the edit was made (UTC)")
    direction: Literal["undo", "redo"]
    landmarks_now: int = Field(description="landmarks in the map now")
    landmarks_after: int = Field(description="landmarks in the map after this step")
    needs_confirmation: bool = Field(description="whole-map step or one emptying the map")


class HistoryPublic(BaseModel):
    """What the caller's next undo and redo would do (null: nothing)."""

    undo: StepPublic | None
    redo: StepPublic | None


class StepResult(HistoryPublic):
    """The step just taken, and the caller's next undo and redo."""

    done: StepPublic


def _public(step: MapStep) -> StepPublic:
    return StepPublic(
        record_id=step.record_id,
        action=step.action,
        landmark_id=step.landmark_id,
        title=step.title,
        t=step.t,
        direction=step.direction,
        landmarks_now=step.landmarks_now,
        landmarks_after=step.landmarks_after,
        needs_confirmation=step.needs_confirmation,
    )


def _history(services: ServicesDep, actor: str) -> HistoryPublic:
    h = services.map.history
    undo, redo = h.next_undo(actor), h.next_redo(actor)
    return HistoryPublic(
        undo=None if undo is None else _public(undo), redo=None if redo is None else _public(redo)
    )


def _result(services: ServicesDep, actor: str, step: MapStep) -> StepResult:
    h = _history(services, actor)
    return StepResult(done=_public(step), undo=h.undo, redo=h.redo)


@router.get("/history")
def map_history(services: ServicesDep, who: Admin) -> HistoryPublic:
    """Your next undo and redo (your own edits only, through the API or the viewer)."""
    return _history(services, who.actor)


@router.post("/undo")
async def undo_map_edit(services: ServicesDep, who: Admin, confirm: bool = Confirm) -> StepResult:
    """Revert your newest map edit still in effect. 409 when there is none, when the
    landmark was changed since by anyone, or when the step needs `confirm=true`."""
    step = await asyncio.to_thread(services.map.history.undo, who.actor, confirm=confirm)
    return _result(services, who.actor, step)


@router.post("/redo")
async def redo_map_edit(services: ServicesDep, who: Admin, confirm: bool = Confirm) -> StepResult:
    """Reapply the map edit you undid last (errors as for undo)."""
    step = await asyncio.to_thread(services.map.history.redo, who.actor, confirm=confirm)
    return _result(services, who.actor, step)

"""`/landmarks`: CRUD, LEDs, blink, battery."""

from __future__ import annotations

from fastapi import APIRouter, HTTPException, Query, Response, status
from pydantic import BaseModel, Field, StrictBool

from live.cells import replace_cells
from live.facades import BatteryStatus
from localizer.events import LedsChanged
from server.auth import Admin, Operator, Viewer
from server.deps import LandmarkId, ServicesDep
from store.errors import ConflictError
from store.models import LandmarkCreate, LandmarkPublic, LandmarkUpdate

router = APIRouter(prefix="/landmarks", tags=["landmarks"])


class LedCommand(BaseModel):
    on: StrictBool  # `{"on": 0}` or `{"on": "yes"}` is refused, not taken as a boolean


class LedState(BaseModel):
    """The site's LED state after a command (confirmed by the radio)."""

    t_ns: int
    all_lit: bool
    lit: list[int]


class BatteryReadingPublic(BaseModel):
    t: str = Field(description="when it was read, UTC, ISO 8601")
    supply_mv: int = Field(description="supply voltage, millivolts")


class BatteryPublic(BaseModel):
    landmark_id: int
    supply_mv: int | None = Field(description="latest reading, millivolts (null: never read)")
    volts: float | None = Field(description="the same in volts (null: never read)")
    percent: float | None = Field(description="rough charge, 0-100 % (null: never read)")
    days_left: float | None = Field(
        description="estimated days until the cut-off voltage (null: not enough readings)"
    )
    history: list[BatteryReadingPublic] = Field(description="readings, oldest first")


class AuditPublic(BaseModel):
    id: int
    t: str
    actor: str
    action: str
    landmark_id: int | None
    before: dict[str, object] | None
    after: dict[str, object] | None
    target_id: int | None = None
    undo_state: str = ""


def _leds(services: ServicesDep, event: LedsChanged) -> LedState:
    return LedState(
        t_ns=event.t_ns,
        all_lit=event.all_lit,
        lit=sorted(services.leds.lit()),
    )


@router.get("")
def list_landmarks(
    services: ServicesDep,
    _: Viewer,
    floor: str | None = Query(None, description="only this floor's landmarks (floor ID)"),
) -> list[LandmarkPublic]:
    if floor is not None:
        services.floors.get(floor)  # 404 naming an unknown floor
        return services.map.on_floor(floor)
    return services.map.list()


@router.post("", status_code=status.HTTP_201_CREATED)
def create_landmark(body: LandmarkCreate, services: ServicesDep, who: Admin) -> LandmarkPublic:
    return services.map.create(body, actor=who.actor)


@router.get("/audit")
def audit_log(
    services: ServicesDep, _: Viewer, limit: int = Query(100, ge=1, le=1000)
) -> list[AuditPublic]:
    return [
        AuditPublic(
            id=r.id or 0,
            t=r.t.isoformat(),
            actor=r.actor,
            action=r.action,
            landmark_id=r.landmark_id,
            before=r.before,
            after=r.after,
            target_id=r.target_id,
            undo_state=r.undo_state,
        )
        for r in services.map.audit(limit)
    ]


@router.get("/{landmark_id}")
def get_landmark(landmark_id: LandmarkId, services: ServicesDep, _: Viewer) -> LandmarkPublic:
    return services.map.get(landmark_id)


@router.patch("/{landmark_id}")
def update_landmark(
    landmark_id: LandmarkId, body: LandmarkUpdate, services: ServicesDep, who: Admin
) -> LandmarkPublic:
    return services.map.update(landmark_id, body, actor=who.actor)


@router.delete("/{landmark_id}", status_code=status.HTTP_204_NO_CONTENT)
def delete_landmark(
    landmark_id: LandmarkId,
    services: ServicesDep,
    who: Admin,
    confirm: bool = Query(False, description="required to delete the map's last landmark"),
) -> Response:
    """Delete a landmark (one step of your undo); the last one needs `confirm=true` (409)."""
    services.map.delete(landmark_id, actor=who.actor, confirm=confirm)
    return Response(status_code=status.HTTP_204_NO_CONTENT)


@router.post("/{landmark_id}/led")
async def set_led(
    landmark_id: LandmarkId, body: LedCommand, services: ServicesDep, _: Operator
) -> LedState:
    """Switch one landmark's LED; 504 naming the landmark when its radio does not answer."""
    return _leds(services, await services.leds.led(landmark_id, body.on))


@router.post("/{landmark_id}/blink")
async def blink(landmark_id: LandmarkId, services: ServicesDep, _: Operator) -> LedState:
    """Blink the LED a few times (to find it on the ceiling), then restore it."""
    return _leds(services, await services.leds.blink(landmark_id))


@router.get("/{landmark_id}/battery")
async def battery(
    landmark_id: LandmarkId,
    services: ServicesDep,
    who: Viewer,
    refresh: bool = Query(False, description="read the supply now (operator role)"),
) -> BatteryPublic:
    """Latest reading, history and days left; `?refresh=true` reads the radio first."""
    if refresh:
        if not who.allows("operator"):
            raise HTTPException(status.HTTP_403_FORBIDDEN, "refresh needs the operator role")
        await services.leds.read_battery(landmark_id)
    return _battery(landmark_id, services.leds.battery(landmark_id))


def _battery(landmark_id: int, st: BatteryStatus) -> BatteryPublic:
    volts = None if st.supply_mv is None else st.supply_mv / 1000.0
    return BatteryPublic(
        landmark_id=landmark_id,
        supply_mv=st.supply_mv,
        volts=volts,
        percent=st.percent,
        days_left=st.days_left,
        history=[BatteryReadingPublic(t=t, supply_mv=mv) for t, mv in st.history],
    )


class CellsReplacedPublic(BaseModel):
    """The landmark's battery after its cells were replaced."""

    battery: BatteryPublic
    read: bool = Field(description="the supply was read after the swap (the radio answered)")
    why_not: str | None = Field(description="why it was not read (null when it was)")


@router.post("/{landmark_id}/cells-replaced")
async def cells_replaced(
    landmark_id: LandmarkId,
    services: ServicesDep,
    who: Operator,
    confirm: bool = Query(False, description="required: the battery trend starts over"),
) -> CellsReplacedPublic:
    """Fresh cells in this landmark: its battery estimate (trend, days left, the energy
    model's days) starts over from readings after now, the low-battery warning re-arms, and
    the supply is read at once (a `cells_replaced` event names who). Needs `confirm=true`
    (409 without it, nothing done)."""
    if not confirm:
        raise ConflictError(
            f"landmark {landmark_id}: cells replaced drops its battery trend so far; "
            "repeat with confirm=true"
        )
    done = await replace_cells(services, landmark_id, actor=who.actor)
    return CellsReplacedPublic(
        battery=_battery(landmark_id, done.battery), read=done.read, why_not=done.why_not
    )

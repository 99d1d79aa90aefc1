"""`/leds`: the LED schedule (`led_policy=scheduled`): what is lit and why, and pins (landmarks
that someone other than the robots needs lit for a while: the survey, a check on a ladder)."""

from __future__ import annotations

from fastapi import APIRouter
from pydantic import BaseModel, Field

from live.leds.runtime import LedScheduler
from server.auth import Operator, Viewer
from server.deps import ServicesDep
from store.errors import ConflictError, NotFoundError

router = APIRouter(prefix="/leds", tags=["leds"])

MAX_PIN_S = 3600.0
"""Longest pin, seconds (a pin is renewed by asking again, not left on by mistake)."""


class PinRequest(BaseModel):
    landmarks: list[int] = Field(min_length=1, max_length=1000, description="landmark IDs")
    reason: str = Field(min_length=1, max_length=120, description="shown in the viewer")
    duration_s: float = Field(
        gt=0, le=MAX_PIN_S, description="keep them lit this long, seconds (asking again renews)"
    )


class PinPublic(BaseModel):
    landmark_id: int
    reason: str
    remaining_s: float = Field(description="seconds until the pin ends")


class LitPublic(BaseModel):
    landmark_id: int
    reason: str = Field(description='why the schedule lights it ("view r1", "pinned: ...")')


class SchedulePublic(BaseModel):
    policy: str = Field(description="`scheduled` or `all_lit`")
    lit: list[LitPublic] = Field(description="what the latest plan lights, and why")
    pinned: list[PinPublic]
    lit_fraction: float = Field(description="share of the landmarks lit, averaged since start")


def _scheduler(services: ServicesDep) -> LedScheduler:
    live = services.runner
    scheduler = None if live is None else live.scheduler
    if scheduler is None:
        raise ConflictError(
            f"led_policy is {services.settings.led_policy!r}: there is no LED schedule "
            "(with all_lit every LED is lit already)"
        )
    return scheduler


def _pins(scheduler: LedScheduler) -> list[PinPublic]:
    return [PinPublic(landmark_id=i, reason=r, remaining_s=s) for i, r, s in scheduler.pins()]


@router.get("/schedule")
def schedule(services: ServicesDep, _: Viewer) -> SchedulePublic:
    """What the schedule lights and why (empty lists with `all_lit`)."""
    live = services.runner
    scheduler = None if live is None else live.scheduler
    if scheduler is None:
        return SchedulePublic(
            policy=services.settings.led_policy, lit=[], pinned=[], lit_fraction=1.0
        )
    plan = scheduler.plan
    reasons = {} if plan is None else plan.reasons
    return SchedulePublic(
        policy="scheduled",
        lit=[LitPublic(landmark_id=i, reason=r) for i, r in sorted(reasons.items())],
        pinned=_pins(scheduler),
        lit_fraction=scheduler.lit_fraction,
    )


@router.post("/pin")
def pin(body: PinRequest, services: ServicesDep, _: Operator) -> list[PinPublic]:
    """Keep these landmarks lit for `duration_s` whatever the robots need (409 with
    `all_lit`; 404 naming an ID that is not a controlled landmark). Returns every pin."""
    scheduler = _scheduler(services)
    controlled = set(scheduler.landmark_ids())
    unknown = sorted(set(body.landmarks) - controlled)
    if unknown:
        raise NotFoundError(f"landmarks {unknown} are not landmarks the radio controls")
    scheduler.pin(body.landmarks, body.reason, body.duration_s)
    return _pins(scheduler)


@router.delete("/pin/{landmark_id}")
def unpin(landmark_id: int, services: ServicesDep, _: Operator) -> list[PinPublic]:
    """End a landmark's pin (404 when it has none). Returns the pins left."""
    scheduler = _scheduler(services)
    if not scheduler.unpin(landmark_id):
        raise NotFoundError(f"landmark {landmark_id} is not pinned")
    return _pins(scheduler)

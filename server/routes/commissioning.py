"""`/commissioning`: doubted landmarks, what to identify, and the identification wizard.

Reads need a viewer key; starting discovery an operator key; driving the wizard (it saves
landmark positions into the map) an admin key, as map edits do. The wizard runs on the
server (`live.commissioning_service.Commissioning`): these routes and the viewer's panel
drive the same one. docs/commissioning.md, docs/api.md.
"""

from __future__ import annotations

import math
from typing import Annotated, Literal

from fastapi import APIRouter, Query
from pydantic import BaseModel, ConfigDict, Field

from commissioning.types import Candidate
from commissioning.wizard import WizardStatus
from server.auth import Admin, Operator, Viewer
from server.deps import ServicesDep
from store.errors import ConflictError
from store.models import MAX_LANDMARK_ID

router = APIRouter(prefix="/commissioning", tags=["commissioning"])
RADIO_PATTERN = r"^[0-9A-Fa-f]{16}$"


class DoubtPublic(BaseModel):
    """A landmark localized robots expected in view but rarely used."""

    landmark_id: int
    chances: int = Field(description="frames in which a settled, localized robot expected it")
    used: int = Field(description="... and used it")
    reason: str


class CandidatePublic(BaseModel):
    """Something to identify: a landmark of the map, or a new radio (with the ID it gets)."""

    landmark_id: int
    radio: str | None = Field(default=None, description="a new radio's 64-bit address")
    reason: str


class WizardStart(BaseModel):
    """What to identify with which robot's camera (at least one landmark or radio)."""

    model_config = ConfigDict(
        json_schema_extra={
            "anyOf": [
                {"required": ["landmarks"], "properties": {"landmarks": {"minItems": 1}}},
                {"required": ["radios"], "properties": {"radios": {"minItems": 1}}},
            ]
        }
    )

    robot: str = Field(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")
    landmarks: list[Annotated[int, Field(ge=0, le=MAX_LANDMARK_ID)]] = Field(
        default_factory=list, max_length=1000, description="landmark IDs of the map"
    )
    radios: list[Annotated[str, Field(pattern=RADIO_PATTERN)]] = Field(
        default_factory=list, max_length=1000, description="new radios (16 hex digits)"
    )


class Position(BaseModel):
    """A landmark's LED position, world frame, metres."""

    x: float = Field(ge=-1e5, le=1e5)
    y: float = Field(ge=-1e5, le=1e5)
    z: float = Field(ge=-1e3, le=1e3)


class WizardConfirm(BaseModel):
    """Save the agreed measurement, or `position` typed by hand."""

    position: Position | None = None
    accept_far: bool = Field(
        default=False, description="confirm a measurement flagged far from the map"
    )


class MeasurementPublic(BaseModel):
    x: float = Field(description="metres, world frame")
    y: float = Field(description="metres, world frame")
    z: float = Field(description="metres, world frame")
    samples: int = Field(description="frames that agree")
    spread_m: float = Field(description="their largest distance from the median, metres")
    distance_from_map_m: float | None = Field(description="horizontal, metres; None: new radio")
    far: bool = Field(description="far from the map: confirming needs accept_far")
    note: str


class WizardStatusPublic(BaseModel):
    phase: Literal["idle", "waiting", "measuring", "done", "cancelled"]
    robot: str
    index: int
    total: int
    candidate: CandidatePublic | None
    prompt: str
    measurement: MeasurementPublic | None
    can_confirm: bool = Field(description="a plausible measurement agrees over several frames")
    needs_accept_far: bool
    waiting_for: list[str] = Field(description="robots that would lose their fix")
    saved: list[int]
    skipped: list[int]


def _candidate(c: Candidate) -> CandidatePublic:
    return CandidatePublic(landmark_id=c.landmark_id, radio=c.radio, reason=c.reason)


def status_public(st: WizardStatus) -> WizardStatusPublic:
    m = st.measurement
    meas = None
    if m is not None:
        x, y, z = m.position
        meas = MeasurementPublic(
            x=x,
            y=y,
            z=z,
            samples=m.samples,
            spread_m=m.spread_m,
            distance_from_map_m=m.plausibility.distance_m,
            far=m.plausibility.far,
            note=m.plausibility.note,
        )
    return WizardStatusPublic(
        phase=st.phase,
        robot=st.robot,
        index=st.index,
        total=st.total,
        candidate=None if st.candidate is None else _candidate(st.candidate),
        prompt=st.prompt,
        measurement=meas,
        can_confirm=st.can_confirm,
        needs_accept_far=st.needs_accept_far,
        waiting_for=list(st.waiting_for),
        saved=list(st.saved),
        skipped=list(st.skipped),
    )


@router.get("/doubts")
def list_doubts(services: ServicesDep, _: Viewer) -> list[DoubtPublic]:
    """The doubted landmarks."""
    return [
        DoubtPublic(landmark_id=d.landmark_id, chances=d.chances, used=d.used, reason=d.reason)
        for d in services.commissioning.doubted().values()
    ]


@router.get("/candidates")
def list_candidates(services: ServicesDep, _: Viewer) -> list[CandidatePublic]:
    """What to identify: the doubted unlocked landmarks, and the new radios of the last
    discovery (`POST /commissioning/candidates/discover`)."""
    found = [(r.address, r.node_id) for r in services.leds.discovered]
    return [_candidate(c) for c in services.commissioning.to_identify(found)]


@router.post("/candidates/discover")
async def discover_candidates(services: ServicesDep, _: Operator) -> list[CandidatePublic]:
    """Run a radio discovery (waits for the radio), then list what to identify."""
    radios = await services.leds.discover()
    found = [(r.address, r.node_id) for r in radios]
    return [_candidate(c) for c in services.commissioning.to_identify(found)]


class CoveragePublic(BaseModel):
    """Coverage of the floor for one robot's camera: row k of `counts` and `error_m` is at
    `ys[k]`, column j at `xs[j]`."""

    robot: str
    xs: list[float] = Field(description="grid x coordinates, metres")
    ys: list[float] = Field(description="grid y coordinates, metres")
    counts: list[list[int]] = Field(description="landmarks in view, fewest over headings")
    error_m: list[list[float | None]] = Field(
        description="expected 1-sigma position error, metres (null: fewer than two in view)"
    )


class SpacingPublic(BaseModel):
    a: int
    b: int
    distance_m: float = Field(description="horizontal, metres")
    problem: str = Field(description='"too_close", or "too_far" (b is a\'s nearest neighbour)')
    allowed_m: tuple[float, float] = Field(description="(min, max) for their height, metres")


@router.get("/coverage")
def get_coverage(
    services: ServicesDep,
    _: Viewer,
    robot: Annotated[str, Query(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$")],
    step_m: Annotated[float, Query(ge=0.05, le=5.0, description="grid step, metres")] = 0.25,
) -> CoveragePublic:
    """Landmarks in view and expected error over the floor for the robot's camera."""
    cov = services.commissioning.coverage(robot, step_m=step_m)
    err = [[None if not math.isfinite(v) else float(v) for v in row] for row in cov.error_m]
    return CoveragePublic(
        robot=robot,
        xs=cov.xs.tolist(),
        ys=cov.ys.tolist(),
        counts=cov.counts.tolist(),
        error_m=err,
    )


@router.get("/spacing")
def get_spacing(services: ServicesDep, _: Viewer) -> list[SpacingPublic]:
    """Landmark pairs spaced outside the recommended 30-150 cm (for a 2.5 m ceiling)."""
    return [
        SpacingPublic(
            a=f.a,
            b=f.b,
            distance_m=f.distance_m,
            problem=f.problem,
            allowed_m=f.allowed_m,
        )
        for f in services.commissioning.spacing()
    ]


@router.get("/wizard")
def wizard_status(services: ServicesDep, _: Viewer) -> WizardStatusPublic:
    """Where the identification wizard stands (poll it while it measures)."""
    return status_public(services.commissioning.status())


@router.post("/wizard/start")
def wizard_start(body: WizardStart, services: ServicesDep, who: Admin) -> WizardStatusPublic:
    """Identify the landmarks and new radios with the robot's camera (409 when running)."""
    c = services.commissioning
    if not body.landmarks and not body.radios:
        raise ValueError("landmarks, radios: name at least one landmark ID or radio address")
    suggested = {
        cand.radio: cand
        for cand in c.to_identify([(r.address, r.node_id) for r in services.leds.discovered])
        if cand.radio
    }
    taken = {lm.id for lm in services.map.list()}
    queue = [Candidate(lid) for lid in body.landmarks]
    for address in body.radios:
        radio = address.upper()
        known = suggested.get(radio)
        if known is None:
            fresh = [x for x in c.to_identify([(radio, "")]) if x.radio == radio]
            if not fresh:
                raise ConflictError(f"radios: {radio} belongs to a landmark of the map")
            known = fresh[0]
        if known.landmark_id in taken:
            raise ConflictError(f"radios: {radio} would get landmark ID {known.landmark_id}, taken")
        taken.add(known.landmark_id)
        queue.append(known)
    return status_public(c.start_wizard(body.robot, queue, actor=who.actor))


@router.post("/wizard/confirm")
def wizard_confirm(body: WizardConfirm, services: ServicesDep, who: Admin) -> WizardStatusPublic:
    """Save the agreed measurement (422 when there is none, or it is far and `accept_far`
    is not set) or the position given, then go on to the next."""
    p = body.position
    position = None if p is None else (p.x, p.y, p.z)
    st = services.commissioning.confirm(
        actor=who.actor, position=position, accept_far=body.accept_far
    )
    return status_public(st)


@router.post("/wizard/skip")
def wizard_skip(services: ServicesDep, who: Admin) -> WizardStatusPublic:
    """Leave the current one as it is and go on to the next."""
    return status_public(services.commissioning.skip(actor=who.actor))


@router.post("/wizard/switch-anyway")
def wizard_switch_anyway(services: ServicesDep, who: Admin) -> WizardStatusPublic:
    """Darken the landmark although a robot tracks with it (it falls back to dead reckoning
    for a moment)."""
    return status_public(services.commissioning.switch_anyway(actor=who.actor))


@router.post("/wizard/cancel")
def wizard_cancel(services: ServicesDep, who: Admin) -> WizardStatusPublic:
    """Stop; every LED the wizard switched is given back."""
    return status_public(services.commissioning.cancel(actor=who.actor))

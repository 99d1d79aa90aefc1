"""`/commissioning/map-proposals`: what the robots' views say should change in the map.

Reading needs a viewer key; accepting (it writes landmark positions into the map) and
rejecting an admin key, as map edits do. The estimator runs on the server
(`live.upkeep_service.MapUpkeepService`); these routes and the viewer's panel are two
clients of it. docs/map-upkeep.md, docs/api.md.
"""

from __future__ import annotations

from typing import Annotated, Literal

from fastapi import APIRouter
from pydantic import BaseModel, Field

from live.upkeep_service import UpkeepStatus
from server.auth import Admin, Viewer
from server.deps import ServicesDep
from store.models import MAX_LANDMARK_ID

router = APIRouter(prefix="/commissioning/map-proposals", tags=["commissioning"])
LandmarkId = Annotated[int, Field(ge=0, le=MAX_LANDMARK_ID)]


class Point(BaseModel):
    """A landmark's LED position, world frame, metres."""

    x: float
    y: float
    z: float


class MapProposalPublic(BaseModel):
    """A change of one landmark's position the robots' views call for."""

    landmark_id: int
    kind: Literal["moved", "refined"] = Field(
        description="moved: beyond its stated uncertainty; refined: within it, known better"
    )
    locked: bool = Field(description="the landmark is locked (surveyed): staff decide")
    old: Point = Field(description="the map's position")
    proposed: Point = Field(description="where the views put it")
    sigma_m: float = Field(description="1-sigma uncertainty of `proposed`, metres")
    shift_m: float = Field(description="distance between old and proposed, metres")
    views: int = Field(description="frames that saw it (the evidence)")
    statistic: float = Field(description="chi-square against the map, 3 degrees of freedom")


class MapUpkeepPublic(BaseModel):
    """The proposals, with how much the robots have seen."""

    frames: int = Field(description="frames that gave evidence since the site started")
    landmarks_seen: int = Field(description="landmarks with evidence")
    proposals: list[MapProposalPublic]


class ProposalsAccept(BaseModel):
    """Which proposals to write into the map (absent: every one of an unlocked landmark)."""

    landmarks: list[LandmarkId] | None = Field(
        default=None, max_length=100_000, description="landmark IDs with a proposal"
    )


class ProposalsReject(BaseModel):
    """Which proposals to reject (their evidence is dropped; the map is not changed)."""

    landmarks: list[LandmarkId] = Field(min_length=1, max_length=100_000)


class ProposalsDone(BaseModel):
    """What was done, and the proposals after it."""

    done: list[int] = Field(description="landmarks accepted (written) or rejected")
    status: MapUpkeepPublic


def status_public(st: UpkeepStatus) -> MapUpkeepPublic:
    out = []
    for v in st.proposals:
        p = v.proposal
        out.append(
            MapProposalPublic(
                landmark_id=p.landmark_id,
                kind=p.kind,
                locked=v.locked,
                old=Point(x=p.old[0], y=p.old[1], z=p.old[2]),
                proposed=Point(x=p.proposed[0], y=p.proposed[1], z=p.proposed[2]),
                sigma_m=p.sigma_m,
                shift_m=p.shift_m,
                views=p.views,
                statistic=p.statistic,
            )
        )
    return MapUpkeepPublic(frames=st.frames, landmarks_seen=st.landmarks_seen, proposals=out)


@router.get("")
def list_map_proposals(services: ServicesDep, _: Viewer) -> MapUpkeepPublic:
    """Landmarks that moved beyond their uncertainty, then refined ones."""
    return status_public(services.upkeep.status())


@router.post("/accept")
def accept_map_proposals(body: ProposalsAccept, services: ServicesDep, who: Admin) -> ProposalsDone:
    """Write proposals into the map (audited as "<you> (map upkeep)", undoable with
    `POST /map/undo`). 409 naming landmarks without a proposal now (nothing written)."""
    done = services.upkeep.accept(body.landmarks, actor=who.actor)
    return ProposalsDone(done=done, status=status_public(services.upkeep.status()))


@router.post("/reject")
def reject_map_proposals(body: ProposalsReject, services: ServicesDep, who: Admin) -> ProposalsDone:
    """Reject proposals: their landmarks' evidence is gathered afresh. 409 naming landmarks
    without a proposal now (nothing dropped)."""
    done = services.upkeep.reject(body.landmarks, actor=who.actor)
    return ProposalsDone(done=done, status=status_public(services.upkeep.status()))

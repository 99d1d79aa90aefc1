"""Injected types shared by the routes (declared once)."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Path
from starlette.requests import HTTPConnection

from server.models import MAX_LANDMARK_ID
from server.services import SiteServices


def get_services(conn: HTTPConnection) -> SiteServices:
    services: SiteServices = conn.app.state.services
    return services


ServicesDep = Annotated[SiteServices, Depends(get_services)]
LandmarkId = Annotated[int, Path(ge=0, le=MAX_LANDMARK_ID, description="landmark ID")]
RobotName = Annotated[
    str, Path(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$", description="robot")
]

"""Injected types shared by the routes (declared once)."""

from __future__ import annotations

from typing import Annotated

from fastapi import Depends, Path
from pydantic import BeforeValidator
from starlette.requests import HTTPConnection

from live.services import SiteServices
from store.models import DECIMAL_ID, MAX_LANDMARK_ID


def get_services(conn: HTTPConnection) -> SiteServices:
    services: SiteServices = conn.app.state.services
    return services


ServicesDep = Annotated[SiteServices, Depends(get_services)]


def _decimal_id(value: object) -> object:
    """A path's landmark ID must be plain decimal digits (`1_00`, `+100`, `100.0` are not)."""
    if isinstance(value, str) and not DECIMAL_ID.fullmatch(value):
        raise ValueError(f"landmark_id: expected a plain decimal integer, got {value!r}")
    return value


LandmarkId = Annotated[
    int,
    Path(ge=0, le=MAX_LANDMARK_ID, description="landmark ID (plain decimal digits)"),
    BeforeValidator(_decimal_id),
]
RobotName = Annotated[
    str, Path(min_length=1, max_length=64, pattern=r"^[A-Za-z0-9_.-]+$", description="robot")
]

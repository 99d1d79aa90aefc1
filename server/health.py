"""The site's health at a glance (`/healthz` and the home page)."""

from __future__ import annotations

from pydantic import BaseModel

from live.services import SiteServices


class Health(BaseModel):
    status: str
    robots: int
    landmarks: int
    radio: str


def site_health(s: SiteServices) -> Health:
    """Robots and landmarks known, and the radio link's state ("absent" without a radio)."""
    return Health(
        status="ok",
        robots=len(s.robots.names()),
        landmarks=s.map.count(),
        radio=s.leds.radio_state,
    )

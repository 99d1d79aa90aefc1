"""`/alerts`: the active alerts, their history (raised and resolved, from the site events),
and a test message to the webhooks (docs/alerts.md)."""

from __future__ import annotations

from typing import Literal

from fastapi import APIRouter, Query
from pydantic import BaseModel, Field

from live.alerts import AlertKind, Severity
from server.auth import Operator, Viewer
from server.deps import ServicesDep

router = APIRouter(tags=["alerts"])
HISTORY_KINDS = ("alert_raised", "alert_resolved")


class AlertPublic(BaseModel):
    """One alert as it stands."""

    key: str = Field(description="`<kind>:<subject>`, unique among the active alerts")
    kind: AlertKind
    subject: str = Field(description="the robot's name, the landmark's id, or `radio`")
    severity: Severity
    active: bool
    message: str = Field(description="for people")
    robot: str | None
    landmark_id: int | None
    data: dict[str, object] = Field(description="details (kind-specific)")
    raised_at: str = Field(description="ISO 8601, UTC")
    resolved_at: str | None = Field(description="ISO 8601, UTC; null while active")


class AlertChange(AlertPublic):
    """A notification: an alert raised or resolved, as SSE, MQTT and webhooks carry it."""

    event_id: int = Field(description="the site event's id (page back with ?before_id=)")
    state: Literal["raised", "resolved"]
    seq: int = Field(description="increasing per server run")
    site: str
    text: str = Field(description="one line for people (chat webhooks show it)")


class WebhookTest(BaseModel):
    urls: int = Field(description="webhooks the test message was queued for")
    body: dict[str, object]


@router.get("/alerts")
def list_alerts(services: ServicesDep, _: Viewer) -> list[AlertPublic]:
    """The active alerts, oldest first."""
    return [AlertPublic(**a.to_dict()) for a in services.alerts.active()]


@router.get("/alerts/history")
def alert_history(
    services: ServicesDep,
    _: Viewer,
    limit: int = Query(100, ge=1, le=1000),
    robot: str | None = Query(None, max_length=64, description="only this robot's alerts"),
    before_id: int | None = Query(
        None, ge=1, description="older than this event id: the next page"
    ),
) -> list[AlertChange]:
    """Alerts raised and resolved, newest first (kept as site events, with their
    retention)."""
    events = services.events.recent(limit, kinds=HISTORY_KINDS, before_id=before_id, robot=robot)
    out = []
    for e in events:
        if "key" in e.data:
            out.append(AlertChange(event_id=e.id, **e.data))
    return out


@router.post("/alerts/test")
def test_webhooks(services: ServicesDep, _: Operator) -> WebhookTest:
    """Send a test message to every configured webhook (`state: "test"`); delivery is
    in the background, as for alerts (failures in the log and `/metrics`)."""
    return WebhookTest(**services.alerts.send_test())

"""`/healthz` degrades (503, naming what) when the database does not answer or cannot
store events; 200 when all is well."""

from __future__ import annotations

import pytest
from sqlalchemy.exc import OperationalError

import server.health
from tests.server.conftest import Api


def test_healthz_is_ok_when_all_is_well(api: Api) -> None:
    r = api.client.get("/healthz")
    assert r.status_code == 200 and r.json()["status"] == "ok" and r.json()["problems"] == []


def test_healthz_names_a_database_that_does_not_answer(
    api: Api, monkeypatch: pytest.MonkeyPatch
) -> None:
    def down(_: object) -> None:
        raise OperationalError("SELECT 1", {}, Exception("connection refused"))

    monkeypatch.setattr(server.health, "_select_one", down)
    r = api.client.get("/healthz")
    assert r.status_code == 503 and r.json()["status"] == "degraded"
    assert r.json()["problems"] == ["database unavailable: connection refused"]


def test_healthz_names_events_that_cannot_be_stored(api: Api) -> None:
    writer = api.services.events.writer
    writer.problem = "database unavailable: events cannot be stored (database is locked)"
    try:
        r = api.client.get("/healthz")
    finally:
        writer.problem = None
    assert r.status_code == 503 and "events cannot be stored" in r.json()["problems"][0]

"""The reliability counters on `/metrics`: edge refusals, bad keys, connections, event
storage failures, supervisor restarts, the fleet link and alerts, in Prometheus' text."""

from __future__ import annotations

import time
from typing import Any

from prometheus_client.parser import text_string_to_metric_families

from server.cli import uvicorn_config
from tests.server.conftest import Api


def scrape(api: Api) -> dict[tuple[str, tuple[tuple[str, str], ...]], float]:
    text = api.client.get("/api/v1/metrics", headers=api.h("viewer")).text
    return {
        (s.name, tuple(sorted(s.labels.items()))): s.value
        for family in text_string_to_metric_families(text)
        for s in family.samples
    }


def test_refusals_bad_keys_and_storage_failures_are_counted(api: Api) -> None:
    c = api.client
    before = scrape(api)
    assert before[("irloc_event_store_ok", ())] == 1.0
    assert before[("irloc_site_thread_restarts_total", ())] == 0.0
    assert before[("irloc_alerts_active", (("kind", "robot_lost"),))] == 0.0
    assert before[("irloc_webhook_bodies_total", (("outcome", "delivered"),))] == 0.0
    assert ("irloc_connections_open", ()) not in before  # not under `irloc serve` here
    assert c.post("/api/v1/landmarks", content=b"{}").status_code == 401  # body, no key
    assert c.get("/api/v1/robots", headers={"Authorization": "Bearer nope"}).status_code == 401
    writer = api.services.events.writer
    store = writer.log.add_event
    calls = {"n": 0}

    def fails_once(*args: Any, **kwargs: Any) -> Any:
        calls["n"] += 1
        if calls["n"] == 1:
            raise OSError(5, "Input/output error")
        return store(*args, **kwargs)

    writer.log.add_event = fails_once  # type: ignore[method-assign]
    api.services.events.emit("map_changed", "a change stored at the second try")
    deadline = time.monotonic() + 10.0  # kept, then stored by the writer's retry (0.25 s)
    while writer.written == 0 and time.monotonic() < deadline:
        time.sleep(0.05)
    after = scrape(api)
    assert after[("irloc_edge_refusals_total", (("status", "401"),))] == 1.0
    assert after[("irloc_edge_bodies_without_key_total", ())] == 1.0
    assert after[("irloc_bad_keys_total", ())] >= 1.0
    assert after[("irloc_event_store_failures_total", ())] == 1.0
    written = ("irloc_events_written_total", ())
    assert after[written] == before[written] + 1
    assert after[("irloc_event_store_ok", ())] == 1.0  # stored again


def test_connection_counters_appear_under_the_guarded_server(api: Api) -> None:
    uvicorn_config(api.services.settings, api.client.app)  # what `irloc serve` runs
    got = scrape(api)
    assert got[("irloc_connections_open", ())] == 0.0
    assert got[("irloc_connections_refused_total", ())] == 0.0

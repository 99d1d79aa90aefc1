"""The HTTP edge: a key before a body, bounded bodies (413 as soon as passed), answers for a
failing database or disk (503 / 507), a throttle that never refuses a valid key, one log
line per burst of bad keys, security headers, forwarded-for only from configured proxies."""

from __future__ import annotations

import asyncio
import errno
import logging
from typing import Any

import pytest
from sqlalchemy.exc import OperationalError

from live.settings import Settings
from server.cli import uvicorn_config
from server.edge import EdgeGuard, body_limit
from server.logs import QuietRefusals
from server.stream_guard import draining
from tests.server.conftest import Api


class Never:
    """An ASGI receive that must not be called (the body must stay unread)."""

    calls = 0

    async def __call__(self) -> dict[str, Any]:
        self.calls += 1
        raise AssertionError("the body was read")


def scope_of(api: Api, method: str, path: str, headers: dict[str, str]) -> dict[str, Any]:
    return {
        "type": "http",
        "method": method,
        "path": path,
        "raw_path": path.encode(),
        "query_string": b"",
        "headers": [(k.lower().encode(), v.encode()) for k, v in headers.items()],
        "client": ("10.0.0.9", 5000),
        "app": api.client.app,
        "state": {},
    }


def run_guard(api: Api, scope: dict[str, Any], receive: Any, inner: Any = None) -> list[Any]:
    sent: list[Any] = []

    async def send(message: Any) -> None:
        sent.append(message)

    async def echo(scope: Any, receive: Any, send: Any) -> None:  # reads its whole body
        while (await receive()).get("more_body", False):
            pass
        await send({"type": "http.response.start", "status": 200, "headers": []})
        await send({"type": "http.response.body", "body": b"{}"})

    guard = EdgeGuard(inner or echo)
    api.client.portal.call(guard, scope, receive, send)  # type: ignore[union-attr]
    return sent


def test_a_body_without_a_valid_key_is_refused_401_unread(api: Api) -> None:
    never = Never()
    for headers in ({}, {"Authorization": "Bearer irloc_not-a-key-at-all-0000000000"}):
        scope = scope_of(api, "PUT", "/api/v1/map", {"content-length": "5000000", **headers})
        sent = run_guard(api, scope, never)
        assert sent[0]["status"] == 401
    assert never.calls == 0


def test_a_declared_length_over_the_limit_is_413_at_once(api: Api) -> None:
    never = Never()
    big = str(body_limit("PUT", "/api/v1/map") + 1)
    sent = run_guard(api, scope_of(api, "PUT", "/api/v1/map", {"content-length": big}), never)
    assert sent[0]["status"] == 413 and never.calls == 0


def test_a_streamed_body_is_cut_off_as_soon_as_it_passes_the_limit(api: Api) -> None:
    chunk = b"x" * 65536
    reads = 0

    async def endless() -> dict[str, Any]:
        nonlocal reads
        reads += 1
        return {"type": "http.request", "body": chunk, "more_body": True}

    headers = {"transfer-encoding": "chunked", **api.h("admin")}
    sent = run_guard(api, scope_of(api, "PUT", "/api/v1/floorplan", headers), endless)
    assert sent[0]["status"] == 413
    limit = body_limit("PUT", "/api/v1/floorplan")
    assert reads == limit // len(chunk) + 1  # not one chunk more


def test_large_bodies_through_the_app_answer_413_and_small_ones_pass(api: Api) -> None:
    r = api.client.patch(
        "/api/v1/landmarks/1", headers=api.h("admin"), content=b"{" + b" " * (2 << 20) + b"}"
    )
    assert r.status_code == 413 and "bytes" in r.json()["detail"]
    r = api.client.put("/api/v1/map", content=b"x" * 100_000)  # no key: 401, not 422
    assert r.status_code == 401
    r = api.client.get("/api/v1/landmarks", headers=api.h("viewer"))
    assert r.status_code == 200
    assert r.headers["x-frame-options"] == "DENY"
    assert "frame-ancestors 'none'" in r.headers["content-security-policy"]


def test_an_upload_cut_by_the_shutdown_is_answered_503(api: Api) -> None:
    async def hangs(scope: Any, receive: Any, send: Any) -> None:
        draining(scope["app"]).set()
        raise asyncio.CancelledError  # what uvicorn does once the grace is over

    scope = scope_of(api, "POST", "/api/v1/robots/r1/calibration/lens", api.h("admin"))
    try:
        sent = run_guard(api, scope, Never(), inner=hangs)
    finally:
        draining(api.client.app).clear()
    assert sent[0]["status"] == 503
    assert b"shutting down" in sent[1]["body"]


@pytest.mark.parametrize(
    ("exc", "status", "word"),
    [
        (OperationalError("SELECT", {}, Exception("server closed")), 503, "database unavailable"),
        (OperationalError("UPDATE", {}, Exception("database is locked")), 503, "busy"),
        (OperationalError("INSERT", {}, Exception("database or disk is full")), 507, "disk full"),
        (OSError(errno.ENOSPC, "No space left on device"), 507, "disk full"),
    ],
)  # fmt: skip
def test_a_failing_database_or_disk_answers_503_or_507_not_500(
    api: Api, monkeypatch: pytest.MonkeyPatch, exc: Exception, status: int, word: str
) -> None:
    def fail(*a: object, **k: object) -> None:
        raise exc

    monkeypatch.setattr(api.services.map, "export_json", fail)
    r = api.client.get("/api/v1/map", headers=api.h("viewer"))
    assert r.status_code == status and word in r.json()["detail"]


def test_a_valid_key_passes_from_a_throttled_address(api: Api) -> None:
    api.services.keys.index_ttl_s = 0.05  # each throttled bad key waits for a new reading
    for i in range(30):
        api.client.get("/api/v1/landmarks", headers={"Authorization": f"Bearer irloc_bad{i:030d}"})
    r = api.client.get("/api/v1/landmarks", headers={"Authorization": "Bearer irloc_" + "z" * 30})
    assert r.status_code == 429
    fresh, _ = api.services.keys.create("viewer", name="made while throttled")
    api.services.keys._cache.clear()  # not cached: as after its TTL
    for _ in range(2):
        r = api.client.get("/api/v1/landmarks", headers={"Authorization": f"Bearer {fresh}"})
        assert r.status_code == 200
        api.services.keys._cache.clear()


def test_bad_keys_are_logged_once_per_burst_and_not_in_the_access_log(
    api: Api, caplog: pytest.LogCaptureFixture
) -> None:
    api.services.keys.index_ttl_s = 0.01
    with caplog.at_level(logging.WARNING, logger="server.throttle"):
        for i in range(40):
            api.client.get("/api/v1/robots", headers={"Authorization": f"Bearer irloc_x{i:030d}"})
    lines = [r for r in caplog.records if r.name == "server.throttle"]
    assert len(lines) == 1 and "bad API keys" in lines[0].getMessage()
    access = logging.LogRecord(
        "uvicorn.access", 20, "", 0, "%s - %s %s %s %d", ("a", "GET", "/", "1.1", 401), None
    )
    assert not QuietRefusals().filter(access)
    access.args = ("a", "GET", "/", "1.1", 200)
    assert QuietRefusals().filter(access)


def test_forwarded_for_is_believed_only_from_configured_proxies() -> None:
    plain = uvicorn_config(Settings(site_enabled=False), app=None)
    assert plain.proxy_headers is False
    behind = uvicorn_config(Settings(site_enabled=False, trusted_proxies=["10.1.0.0/16"]), None)
    assert behind.proxy_headers and behind.forwarded_allow_ips == ["10.1.0.0/16"]
    with pytest.raises(ValueError, match="trusted_proxies"):
        Settings(trusted_proxies=["not-an-address"])

"""Answers that name what was wrong: a method on a path of another route is 405 (not a
validation error of the route whose pattern matched), `{"on": 0}` is not a boolean, a
viewer WebSocket from another site's page is refused."""

from __future__ import annotations

from starlette.requests import HTTPConnection

from server.edge import same_origin
from tests.server.conftest import Api


def test_patch_on_the_audit_log_is_405_naming_the_methods(api: Api) -> None:
    r = api.client.patch("/api/v1/landmarks/audit", headers=api.h("admin"), json={})
    assert r.status_code == 405 and r.headers["allow"] == "GET"
    assert "use GET" in r.json()["detail"]
    r = api.client.patch("/api/v1/landmarks/1_00", headers=api.h("admin"), json={})
    assert r.status_code == 422  # a bad ID of the landmark route is still its own error


def test_led_on_must_be_a_json_boolean(api: Api) -> None:
    for bad in (0, 1, "true", "yes", None):
        r = api.client.post("/api/v1/landmarks/1/led", headers=api.h("operator"), json={"on": bad})
        assert r.status_code == 422 and "on" in r.json()["detail"], bad


def conn(headers: dict[str, str]) -> HTTPConnection:
    raw = [(k.encode(), v.encode()) for k, v in headers.items()]
    return HTTPConnection({"type": "websocket", "headers": raw, "path": "/viewer/"})


def test_a_websocket_from_another_sites_page_is_not_same_origin() -> None:
    assert same_origin(conn({"host": "plant:8000", "origin": "http://plant:8000"}))
    assert same_origin(conn({"host": "plant:8000"}))  # not a browser
    assert not same_origin(conn({"host": "plant:8000", "origin": "https://evil.example"}))
    assert not same_origin(conn({"host": "plant:8000", "origin": "http://plant:8001"}))

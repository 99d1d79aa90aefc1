"""Key checks under attack: revocation takes effect at once (also from the CLI, another
process's write), revoked keys lose their open streams, bad keys are throttled per address
and cost the database one lookup each at most."""

from __future__ import annotations

import json
import threading
import time

import pytest
from starlette.websockets import WebSocketDisconnect

from server import keys_cli
from tests.server.conftest import Api


def _key_id(api: Api, role: str) -> int:
    return next(k.id for k in api.services.keys.list() if k.name == f"test {role}")


def test_a_key_revoked_with_the_cli_is_refused_within_a_second(api: Api) -> None:
    c, h = api.client, api.h("operator")
    assert c.get("/api/v1/landmarks", headers=h).status_code == 200
    data_dir = str(api.services.settings.data_dir)
    # the CLI writes the database through its own engine and key store, as `irloc keys` does
    assert keys_cli.main(["revoke", str(_key_id(api, "operator")), "--data-dir", data_dir]) == 0
    t0 = time.monotonic()
    while c.get("/api/v1/landmarks", headers=h).status_code == 200:
        assert time.monotonic() - t0 < 1.0, "the revoked key still works after 1 s"
        time.sleep(0.05)
    assert c.get("/api/v1/landmarks", headers=h).status_code == 401


def test_revoking_a_key_closes_its_pose_websocket_with_1008(api: Api) -> None:
    c = api.client
    with c.websocket_connect("/api/v1/poses/ws", headers=api.h("viewer")) as ws:
        t0 = time.monotonic()
        r = c.delete(f"/api/v1/keys/{_key_id(api, 'viewer')}", headers=api.h("admin"))
        assert r.status_code == 204
        with pytest.raises(WebSocketDisconnect) as exc:
            ws.receive_text()
        assert time.monotonic() - t0 < 1.5
    assert exc.value.code == 1008 and "revoked" in exc.value.reason


def test_revoking_a_key_ends_its_event_stream(api: Api) -> None:
    c = api.client
    revoke_at: list[float] = []

    def revoke() -> None:
        time.sleep(0.3)
        revoke_at.append(time.monotonic())
        c.delete(f"/api/v1/keys/{_key_id(api, 'viewer')}", headers=api.h("admin"))

    with c.stream("GET", "/api/v1/events/stream", headers=api.h("viewer")) as r:
        assert r.status_code == 200
        threading.Thread(target=revoke, daemon=True).start()
        text = "".join(r.iter_text())  # returns only when the server ends the stream
    assert time.monotonic() - revoke_at[0] < 1.5
    assert "event: key_revoked" in text


def test_the_same_bad_key_reaches_the_database_once(api: Api) -> None:
    keys = api.services.keys
    before = keys.lookups
    for _ in range(30):
        r = api.client.get("/api/v1/landmarks", headers={"Authorization": "Bearer irloc_bad"})
        assert r.status_code in (401, 429)
    assert keys.lookups - before == 1


def test_bad_keys_are_throttled_per_address_and_looked_up_off_the_loop(api: Api) -> None:
    keys = api.services.keys
    keys.index_ttl_s = 0.01  # a throttled key waits for the next reading of valid keys
    before = keys.lookups
    codes = [
        api.client.get(
            "/api/v1/landmarks", headers={"Authorization": f"Bearer irloc_guess{i}"}
        ).status_code
        for i in range(60)
    ]
    assert codes[0] == 401 and codes[-1] == 429
    assert keys.lookups - before <= 20, keys.lookups - before
    r = api.client.get("/api/v1/landmarks", headers={"Authorization": "Bearer irloc_more"})
    assert r.status_code == 429 and int(r.headers["retry-after"]) >= 1
    assert "too many" in r.json()["detail"]
    # the budget refills at one key a second: a valid key from the same address works again
    time.sleep(1.1)
    assert api.client.get("/api/v1/landmarks", headers=api.h("viewer")).status_code == 200
    # every lookup ran on a worker thread, never on the event loop's
    assert keys.lookup_threads and all(t.startswith("key-lookup") for t in keys.lookup_threads)


def test_error_bodies_are_json_with_a_detail(api: Api) -> None:
    r = api.client.get("/api/v1/landmarks")
    assert r.status_code == 401 and isinstance(json.loads(r.text)["detail"], str)

"""Every endpoint but /healthz needs a key; roles viewer < operator < admin."""

from __future__ import annotations

from pathlib import Path

import pytest

from server import keys_cli
from store.db import make_engine, migrate
from store.keys import KeyStore
from tests.server.conftest import LM, Api

# (method, path, body, lowest role allowed)
CASES = [
    ("GET", "/api/v1/landmarks", None, "viewer"),
    ("GET", "/api/v1/map", None, "viewer"),
    ("GET", "/api/v1/robots", None, "viewer"),
    ("GET", "/api/v1/events", None, "viewer"),
    ("GET", "/api/v1/metrics", None, "viewer"),
    ("GET", "/api/v1/landmarks/11/battery", None, "viewer"),
    ("GET", "/api/v1/landmarks/11/battery?refresh=true", None, "operator"),
    ("POST", "/api/v1/landmarks/11/led", {"on": False}, "operator"),
    ("POST", "/api/v1/radio/discover", None, "operator"),
    ("PATCH", "/api/v1/landmarks/11", {"note": "x"}, "admin"),
    ("PUT", "/api/v1/map", {"landmarks": [LM]}, "admin"),
    ("GET", "/api/v1/keys", None, "admin"),
    ("POST", "/api/v1/keys", {"role": "viewer"}, "admin"),
]
RANK = {"viewer": 0, "operator": 1, "admin": 2}


@pytest.mark.parametrize(("method", "path", "body", "needed"), CASES)
def test_roles(api: Api, method: str, path: str, body: object, needed: str) -> None:
    api.client.post("/api/v1/landmarks", json=LM, headers=api.h("admin"))
    r = api.client.request(method, path, json=body)
    assert r.status_code == 401 and r.headers["www-authenticate"] == "Bearer"
    r = api.client.request(method, path, json=body, headers={"Authorization": "Bearer nope"})
    assert r.status_code == 401
    for role in ("viewer", "operator", "admin"):
        r = api.client.request(method, path, json=body, headers=api.h(role))
        if RANK[role] < RANK[needed]:
            assert r.status_code == 403, (role, r.text)
            assert needed in r.json()["detail"]
        else:
            # allowed: anything but an auth refusal (503 = no radio in this app)
            assert r.status_code not in (401, 403), (role, r.text)


def test_healthz_needs_no_key(api: Api) -> None:
    r = api.client.get("/healthz")
    assert r.status_code == 200 and r.json()["status"] == "ok"


def test_revoked_key_is_refused(api: Api) -> None:
    c = api.client
    assert c.get("/api/v1/landmarks", headers=api.h("viewer")).status_code == 200
    key_id = next(k.id for k in api.services.keys.list() if k.role == "viewer")
    assert c.delete(f"/api/v1/keys/{key_id}", headers=api.h("admin")).status_code == 204
    assert c.get("/api/v1/landmarks", headers=api.h("viewer")).status_code == 401


def test_token_query_parameter_is_accepted(api: Api) -> None:
    r = api.client.get(f"/api/v1/landmarks?token={api.keys['viewer']}")
    assert r.status_code == 200


def test_keys_are_stored_hashed(api: Api) -> None:
    import sqlite3

    db = api.services.settings.data_dir / "irloc.db"
    rows = sqlite3.connect(db).execute("SELECT hash, prefix FROM api_keys").fetchall()
    assert len(rows) == 3
    for key in api.keys.values():
        assert all(key not in (h, p) for h, p in rows)


def test_last_use_is_recorded_at_most_once_a_minute_per_key(tmp_path: Path) -> None:
    engine = make_engine(f"sqlite:///{tmp_path / 'keys.db'}")
    migrate(engine)
    now = [1000.0]
    store = KeyStore(engine, clock=lambda: now[0])
    key, rec = store.create("viewer", "k")
    other, _ = store.create("operator", "o")
    assert rec.last_used_at is None
    for t in (1000.0, 1010.0, 1059.9):  # one write for the first minute
        now[0] = t
        assert store.role_of(key) == (rec.id, "viewer")
    first = store.list()[0].last_used_at
    assert store.touches == 1 and first is not None
    store.role_of(other)  # another key has its own minute
    now[0] = 1060.0
    store.role_of(key)
    listed = {k.id: k.last_used_at for k in store.list()}
    second = listed[rec.id]
    assert store.touches == 3 and second is not None and second >= first
    assert store.role_of("irloc_unknown") is None and store.touches == 3
    store.close()
    engine.dispose()


def test_admin_api_and_cli_show_last_use(
    api: Api, db_url: str, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("IRLOC_DATABASE_URL", db_url)  # the CLI reads the same database
    api.client.get("/api/v1/landmarks", headers=api.h("viewer"))
    keys = api.client.get("/api/v1/keys", headers=api.h("admin")).json()
    used = {k["name"]: k["last_used_at"] for k in keys}
    assert used["test viewer"] is not None and used["test operator"] is None
    assert keys_cli.main(["list", "--data-dir", str(api.services.settings.data_dir)]) == 0
    rows = [line.split("\t") for line in capsys.readouterr().out.splitlines()]
    assert rows[0][5] == "last used (UTC)"
    by_name = {r[6]: r[5] for r in rows[1:]}
    assert by_name["test operator"] == "never" and by_name["test viewer"][:2] == "20"

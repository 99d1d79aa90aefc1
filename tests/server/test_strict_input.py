"""Malformed and lax input gets a 4xx naming the problem, never a 500, and changes nothing:
deep JSON, huge or broken CSV fields, non-integer IDs, extra CSV fields, an empty import."""

from __future__ import annotations

from collections.abc import Iterator

import pytest

from tests.server.conftest import LM, Api, start_api

CSV_HEAD = "id,x,y,z,radio,locked,note\n"


def _count(api: Api) -> int:
    return len(api.client.get("/api/v1/landmarks", headers=api.h("viewer")).json())


@pytest.fixture(scope="module")
def shared(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Api]:
    """One app for the module (each test sets the map it needs)."""
    yield from start_api(tmp_path_factory.mktemp("strict"), site_enabled=False)


@pytest.fixture
def api(shared: Api) -> Api:
    """The shared app with an empty map."""
    r = shared.client.put(
        "/api/v1/map?allow_empty=true", json={"landmarks": []}, headers=shared.h("admin")
    )
    assert r.status_code == 200, r.text
    return shared


@pytest.fixture
def mapped(api: Api) -> Api:
    """The shared app with one landmark."""
    r = api.client.put("/api/v1/map", json={"landmarks": [LM]}, headers=api.h("admin"))
    assert r.status_code == 200, r.text
    return api


@pytest.mark.parametrize(
    ("body", "ctype", "says"),
    [
        ("[" * 100_000 + "]" * 100_000, "application/json", "nested"),
        ('{"landmarks": ' + "[" * 5000 + "]" * 5000 + "}", "application/json", "nested"),
        (CSV_HEAD + "1,0,0,2.5,,," + "n" * 131_073 + "\n", "text/csv", "line 2: a field"),
        (CSV_HEAD + "1,0,0,2.5,,,a\rb\n", "text/csv", "line 2"),
        (CSV_HEAD + "1,0,0,2.5,,,note,surplus\n", "text/csv", "line 2: 8 fields"),
        ("id,x,y,z,colour\n1,0,0,2.5,red\n", "text/csv", "colour"),
        (b"\xff\xfe{".decode("latin-1"), "application/json", "UTF-8"),
    ],
)
def test_malformed_maps_are_4xx_naming_the_problem(
    mapped: Api, body: str, ctype: str, says: str
) -> None:
    r = mapped.client.put(
        "/api/v1/map",
        content=body.encode("latin-1") if says == "UTF-8" else body.encode(),
        headers={**mapped.h("admin"), "Content-Type": ctype},
    )
    assert 400 <= r.status_code < 500, r.text[:300]
    assert says in r.json()["detail"], r.json()["detail"][:300]
    assert _count(mapped) == 1  # the map is untouched


@pytest.mark.parametrize("value", [True, "1", "1_000", 1.5, "+100", None, [1]], ids=repr)
def test_landmark_ids_must_be_json_integers(api: Api, value: object) -> None:
    r = api.client.post("/api/v1/landmarks", json={**LM, "id": value}, headers=api.h("admin"))
    assert r.status_code == 422, (value, r.text)
    assert "id" in r.json()["detail"] and "integer" in r.json()["detail"], r.json()["detail"]
    assert _count(api) == 0


@pytest.mark.parametrize("path", ["1_00", "+100", "100.0", " 100", "0100", "1e2", "0x64"])
def test_landmark_ids_in_paths_are_plain_decimal(api: Api, path: str) -> None:
    api.client.post("/api/v1/landmarks", json={**LM, "id": 100}, headers=api.h("admin"))
    assert api.client.get("/api/v1/landmarks/100", headers=api.h("viewer")).status_code == 200
    r = api.client.get(f"/api/v1/landmarks/{path}", headers=api.h("viewer"))
    assert r.status_code == 422, (path, r.text)
    assert "landmark_id" in r.json()["detail"] and "decimal" in r.json()["detail"]


def test_csv_ids_are_strict_and_a_bom_is_accepted(mapped: Api) -> None:
    h = {**mapped.h("admin"), "Content-Type": "text/csv"}
    for bad in ("1_000", "+5", "5.0", " 5"):
        r = mapped.client.put("/api/v1/map", content=f"{CSV_HEAD}{bad},0,0,2.5,,,\n", headers=h)
        assert r.status_code == 422 and "line 2: id" in r.json()["detail"], (bad, r.text)
    bom = "\ufeff" + CSV_HEAD + "5,0.5,0,2.5,,true,by the door\n6,1,0,2.5,,,\n"
    r = mapped.client.put("/api/v1/map", content=bom.encode("utf-8"), headers=h)
    assert r.status_code == 200 and r.json() == {"landmarks": 2}, r.text
    got = mapped.client.get("/api/v1/landmarks/5", headers=mapped.h("viewer")).json()
    assert got["locked"] is True and got["note"] == "by the door"


def test_an_empty_import_needs_allow_empty(mapped: Api) -> None:
    c, h = mapped.client, mapped.h("admin")
    for body in ({"json": {"landmarks": []}}, {"content": CSV_HEAD}):
        headers = h if "json" in body else {**h, "Content-Type": "text/csv"}
        r = c.put("/api/v1/map", headers=headers, **body)  # type: ignore[arg-type]
        assert r.status_code == 409 and "allow_empty=true" in r.json()["detail"], r.text
        assert _count(mapped) == 1
    r = c.put("/api/v1/map?allow_empty=true", json={"landmarks": []}, headers=h)
    assert r.status_code == 200 and r.json() == {"landmarks": 0} and _count(mapped) == 0


def test_deep_json_to_any_route_is_400(api: Api) -> None:
    deep = "[" * 100_000 + "]" * 100_000
    for method, path in (("POST", "/api/v1/landmarks"), ("PATCH", "/api/v1/landmarks/1")):
        r = api.client.request(
            method, path, content=deep,
            headers={**api.h("admin"), "Content-Type": "application/json"},
        )  # fmt: skip
        assert r.status_code in (400, 422), r.text[:200]
        assert "nested" in r.json()["detail"]

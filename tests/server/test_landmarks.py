"""Landmark CRUD through the API with validation, on a real SQLite file."""

from __future__ import annotations

import numpy as np

from tests.server.conftest import LM, Api


def test_create_get_update_delete_round_trip(api: Api) -> None:
    c, h = api.client, api.h("admin")
    r = c.post("/api/v1/landmarks", json=LM, headers=h)
    assert r.status_code == 201
    got = c.get("/api/v1/landmarks/11", headers=h).json()
    np.testing.assert_allclose([got["x"], got["y"], got["z"]], [0.6, 0.3, 2.5])
    assert got["radio"] == "0013A20041B2C3D4"
    r = c.patch("/api/v1/landmarks/11", json={"z": 2.45, "locked": True}, headers=h)
    assert r.status_code == 200
    assert r.json()["z"] == 2.45 and r.json()["locked"] is True and r.json()["x"] == 0.6
    assert c.delete("/api/v1/landmarks/11", headers=h).status_code == 409  # the last one
    assert c.delete("/api/v1/landmarks/11?confirm=true", headers=h).status_code == 204
    assert c.get("/api/v1/landmarks/11", headers=h).status_code == 404
    actions = [a["action"] for a in c.get("/api/v1/landmarks/audit", headers=h).json()]
    assert actions == ["delete", "update", "create"]


def test_radio_address_is_normalised(api: Api) -> None:
    body = {**LM, "radio": "00:13:a2:00:41:b2:c3:d4"}
    r = api.client.post("/api/v1/landmarks", json=body, headers=api.h("admin"))
    assert r.status_code == 201 and r.json()["radio"] == "0013A20041B2C3D4"


def test_duplicate_id_is_409(api: Api) -> None:
    c, h = api.client, api.h("admin")
    assert c.post("/api/v1/landmarks", json=LM, headers=h).status_code == 201
    r = c.post("/api/v1/landmarks", json={**LM, "radio": None}, headers=h)
    assert r.status_code == 409 and "landmark 11 already exists" in r.json()["detail"]


def test_duplicate_radio_is_409_naming_the_owner(api: Api) -> None:
    c, h = api.client, api.h("admin")
    c.post("/api/v1/landmarks", json=LM, headers=h)
    r = c.post("/api/v1/landmarks", json={**LM, "id": 12}, headers=h)
    assert r.status_code == 409 and "landmark 11" in r.json()["detail"]


def test_nan_coordinate_is_422_naming_the_field(api: Api) -> None:
    body = b'{"id": 5, "x": NaN, "y": 0.0, "z": 2.5}'
    r = api.client.post(
        "/api/v1/landmarks",
        content=body,
        headers={**api.h("admin"), "Content-Type": "application/json"},
    )
    assert r.status_code == 422 and "x" in r.json()["detail"]


def test_absurd_coordinates_are_422(api: Api) -> None:
    c, h = api.client, api.h("admin")
    for field, value in (("x", 1e7), ("y", -2e4), ("z", -0.5), ("z", 250.0)):
        r = c.post("/api/v1/landmarks", json={**LM, field: value}, headers=h)
        assert r.status_code == 422, (field, value)
        assert f"body.{field}" in r.json()["detail"]
    assert c.get("/api/v1/landmarks", headers=h).json() == []


def test_bad_radio_address_is_422(api: Api) -> None:
    r = api.client.post("/api/v1/landmarks", json={**LM, "radio": "12345"}, headers=api.h("admin"))
    assert r.status_code == 422 and "radio" in r.json()["detail"]


def test_patch_unknown_landmark_is_404(api: Api) -> None:
    r = api.client.patch("/api/v1/landmarks/99", json={"x": 1.0}, headers=api.h("admin"))
    assert r.status_code == 404 and "99" in r.json()["detail"]


def test_patch_null_coordinate_is_422(api: Api) -> None:
    c, h = api.client, api.h("admin")
    c.post("/api/v1/landmarks", json=LM, headers=h)
    r = c.patch("/api/v1/landmarks/11", json={"x": None}, headers=h)
    assert r.status_code == 422 and "x" in r.json()["detail"]


def test_led_without_radio_is_503_and_server_carries_on(api: Api) -> None:
    c = api.client
    c.post("/api/v1/landmarks", json=LM, headers=api.h("admin"))
    r = c.post("/api/v1/landmarks/11/led", json={"on": True}, headers=api.h("operator"))
    assert r.status_code == 503
    assert c.get("/api/v1/landmarks/11", headers=api.h("viewer")).status_code == 200


def test_undo_reverts_the_last_change(api: Api) -> None:
    c, h = api.client, api.h("admin")
    c.post("/api/v1/landmarks", json=LM, headers=h)
    c.patch("/api/v1/landmarks/11", json={"x": 5.0}, headers=h)
    r = c.post("/api/v1/map/undo", headers=h)
    assert r.status_code == 200 and r.json()["done"]["title"] == "undo move of landmark 11"
    assert c.get("/api/v1/landmarks/11", headers=h).json()["x"] == 0.6

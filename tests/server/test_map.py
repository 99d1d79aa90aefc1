"""Map import/export (map.json and CSV) through the API."""

from __future__ import annotations

from typing import Any

import numpy as np

from tests.server.conftest import Api

MAP: dict[str, list[dict[str, Any]]] = {
    "landmarks": [
        {"id": 11, "x": 0.6, "y": 0.3, "z": 2.5, "radio": "0013A20041B2C3D4"},
        {"id": 12, "x": 1.35, "y": 0.3, "z": 2.48, "locked": True, "note": "by the door"},
        {"id": 13, "x": -0.75, "y": 2.125, "z": 2.52},
    ]
}


def _xyz(doc: dict[str, Any]) -> np.ndarray:
    return np.array([[lm["id"], lm["x"], lm["y"], lm["z"]] for lm in doc["landmarks"]])


def test_json_import_export_round_trip(api: Api) -> None:
    c, h = api.client, api.h("admin")
    r = c.put("/api/v1/map", json=MAP, headers=h)
    assert r.status_code == 200 and r.json() == {"landmarks": 3}
    out = c.get("/api/v1/map", headers=h).json()
    np.testing.assert_allclose(_xyz(out), _xyz(MAP))
    assert out["landmarks"][0]["radio"] == "0013A20041B2C3D4"
    assert out["landmarks"][1]["locked"] is True and out["landmarks"][1]["note"] == "by the door"


def test_csv_export_then_import_restores_the_map(api: Api) -> None:
    c, h = api.client, api.h("admin")
    c.put("/api/v1/map", json=MAP, headers=h)
    csv_text = c.get("/api/v1/map?format=csv", headers=h).text
    assert csv_text.splitlines()[0] == "id,x,y,z,radio,locked,note,floor"
    assert c.put("/api/v1/map", json={"landmarks": []}, headers=h).status_code == 409
    c.put("/api/v1/map?confirm=true", json={"landmarks": []}, headers=h)
    assert c.get("/api/v1/landmarks", headers=h).json() == []
    r = c.put("/api/v1/map", content=csv_text, headers={**h, "Content-Type": "text/csv"})
    assert r.status_code == 200 and r.json() == {"landmarks": 3}
    np.testing.assert_allclose(_xyz(c.get("/api/v1/map", headers=h).json()), _xyz(MAP))


def test_bad_map_is_refused_and_the_old_map_kept(api: Api) -> None:
    c, h = api.client, api.h("admin")
    c.put("/api/v1/map", json=MAP, headers=h)
    dup = {"landmarks": [MAP["landmarks"][0], {**MAP["landmarks"][2], "id": 11}]}
    r = c.put("/api/v1/map", json=dup, headers=h)
    assert r.status_code == 409 and "duplicate landmark id 11" in r.json()["detail"]
    bad = {"landmarks": [{"id": 1, "x": 0.0, "y": 0.0, "z": 1e6}]}
    r = c.put("/api/v1/map", json=bad, headers=h)
    assert r.status_code == 422 and "landmarks.0.z" in r.json()["detail"]
    r = c.put("/api/v1/map", content="id,x\n1,2\n", headers={**h, "Content-Type": "text/csv"})
    assert r.status_code == 422 and "header" in r.json()["detail"]
    assert len(c.get("/api/v1/landmarks", headers=h).json()) == 3


def test_import_is_audited_and_can_be_undone(api: Api) -> None:
    c, h = api.client, api.h("admin")
    c.put("/api/v1/map", json=MAP, headers=h)
    c.put("/api/v1/map", json={"landmarks": MAP["landmarks"][:1]}, headers=h)
    assert len(api.services.map.list()) == 1
    r = c.post("/api/v1/map/undo?confirm=true", headers=h)
    assert r.status_code == 200 and r.json()["done"]["title"] == "undo map import (3 -> 1 landmark)"
    assert [lm.id for lm in api.services.map.list()] == [11, 12, 13]
    r = c.post("/api/v1/landmarks/11/led", json={"on": True}, headers=api.h("operator"))
    assert r.status_code == 503
    assert c.get("/api/v1/landmarks/11", headers=api.h("viewer")).status_code == 200

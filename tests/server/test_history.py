"""Undo and redo of one's own map edits through the API (`/map/undo`, `/map/redo`)."""

from __future__ import annotations

from typing import Any

from tests.server.conftest import Api

MAP: dict[str, list[dict[str, Any]]] = {
    "landmarks": [
        {"id": 1, "x": 0.0, "y": 0.0, "z": 2.5},
        {"id": 2, "x": 1.0, "y": 0.0, "z": 2.5},
        {"id": 3, "x": 2.0, "y": 0.0, "z": 2.5},
    ]
}


def _ids(api: Api) -> list[int]:
    return [lm.id for lm in api.services.map.list()]


def _title(step: dict[str, Any] | None) -> str | None:
    return None if step is None else str(step["title"])


def test_undo_and_redo_name_each_step_and_stop_at_a_whole_map_change(api: Api) -> None:
    c, h = api.client, api.h("admin")
    c.put("/api/v1/map", json=MAP, headers=h)
    c.patch("/api/v1/landmarks/2", json={"x": 1.25}, headers=h)
    c.patch("/api/v1/landmarks/3", json={"locked": True}, headers=h)
    c.post("/api/v1/landmarks", json={"id": 17, "x": 3.0, "y": 0.5, "z": 2.4}, headers=h)
    hist = c.get("/api/v1/map/history", headers=h).json()
    assert _title(hist["undo"]) == "undo add of landmark 17" and hist["redo"] is None
    titles = [c.post("/api/v1/map/undo", headers=h).json()["done"]["title"] for _ in range(3)]
    assert titles == [
        "undo add of landmark 17",
        "undo lock of landmark 3",
        "undo move of landmark 2",
    ]
    assert api.services.map.get(2).x == 1.0 and not api.services.map.get(3).locked
    # the fourth undo is the import: whole map, refused without a confirmation, map kept
    r = c.post("/api/v1/map/undo", headers=h)
    assert r.status_code == 409
    assert "undo map import (0 -> 3 landmarks)" in r.json()["detail"]
    assert "confirm" in r.json()["detail"] and _ids(api) == [1, 2, 3]
    step = c.get("/api/v1/map/history", headers=h).json()["undo"]
    assert step["needs_confirmation"] and step["landmarks_now"] == 3
    assert step["landmarks_after"] == 0
    # redo goes forward in the order undone, and is itself named
    r = c.post("/api/v1/map/redo", headers=h).json()
    assert r["done"]["title"] == "redo move of landmark 2"
    assert _title(r["redo"]) == "redo lock of landmark 3"
    assert api.services.map.get(2).x == 1.25
    # a new edit drops what could still be redone
    c.patch("/api/v1/landmarks/1", json={"z": 2.45}, headers=h)
    hist = c.get("/api/v1/map/history", headers=h).json()
    assert _title(hist["undo"]) == "undo height change of landmark 1" and hist["redo"] is None
    assert c.post("/api/v1/map/redo", headers=h).status_code == 409
    # confirmed, the import's undo is one step: the map as before it (empty here)
    c.post("/api/v1/map/undo", headers=h)
    c.post("/api/v1/map/undo", headers=h)
    r = c.post("/api/v1/map/undo?confirm=true", headers=h)
    assert r.status_code == 200 and _ids(api) == []
    assert _title(r.json()["redo"]) == "redo map import (0 -> 3 landmarks)"
    r = c.post("/api/v1/map/redo?confirm=true", headers=h)
    assert r.status_code == 200 and _ids(api) == [1, 2, 3]
    actions = [a["action"] for a in c.get("/api/v1/landmarks/audit?limit=3", headers=h).json()]
    assert actions == ["redo", "undo", "undo"]


def test_each_key_undoes_only_its_own_edits(api: Api) -> None:
    c, admin = api.client, api.h("admin")
    other, _ = api.services.keys.create("admin", name="second admin")
    h2 = {"Authorization": f"Bearer {other}"}
    api.services.map.replace_all([_lm(i) for i in (1, 2, 3)], actor="virtual site")
    c.patch("/api/v1/landmarks/1", json={"x": 0.5}, headers=admin)
    c.patch("/api/v1/landmarks/2", json={"x": 1.5}, headers=h2)
    r = c.post("/api/v1/map/undo", headers=admin)
    assert r.json()["done"]["title"] == "undo move of landmark 1"
    assert api.services.map.get(2).x == 1.5  # the other key's edit stays
    # nothing more of the first key's: the server's own import is nobody's to undo
    r = c.post("/api/v1/map/undo", headers=admin)
    assert r.status_code == 409 and "nothing of yours" in r.json()["detail"]
    assert _ids(api) == [1, 2, 3]
    # the viewer acts as viewer:key:<id>: the same key's history
    key_id = api.services.keys.role_of(other)
    assert key_id is not None
    api.services.map.update(3, _upd(z=2.4), actor=f"viewer:key:{key_id[0]}")
    r = c.post("/api/v1/map/undo", headers=h2)
    assert r.json()["done"]["title"] == "undo height change of landmark 3"


def test_an_undo_never_overwrites_a_later_edit_by_someone_else(api: Api) -> None:
    c, admin = api.client, api.h("admin")
    other, _ = api.services.keys.create("admin", name="second admin")
    h2 = {"Authorization": f"Bearer {other}"}
    c.put("/api/v1/map", json=MAP, headers=admin)
    c.patch("/api/v1/landmarks/2", json={"x": 1.1}, headers=admin)
    c.patch("/api/v1/landmarks/2", json={"x": 1.2}, headers=h2)
    r = c.post("/api/v1/map/undo", headers=admin)
    assert r.status_code == 409 and "landmark 2 has changed since" in r.json()["detail"]
    assert api.services.map.get(2).x == 1.2


def test_nothing_leaves_the_site_without_landmarks_unconfirmed(api: Api) -> None:
    c, h = api.client, api.h("admin")
    c.post("/api/v1/landmarks", json={"id": 5, "x": 0.0, "y": 0.0, "z": 2.5}, headers=h)
    r = c.post("/api/v1/map/undo", headers=h)  # undoing the only add empties the map
    assert r.status_code == 409 and "without landmarks" in r.json()["detail"]
    r = c.delete("/api/v1/map", headers=h)
    assert r.status_code == 409 and _ids(api) == [5]
    r = c.delete("/api/v1/landmarks/5", headers=h)
    assert r.status_code == 409 and "last landmark" in r.json()["detail"]
    r = c.delete("/api/v1/map?confirm=true", headers=h)
    assert r.status_code == 200 and _ids(api) == []
    assert c.post("/api/v1/map/undo", headers=h).status_code == 409  # whole map
    r = c.post("/api/v1/map/undo?confirm=true", headers=h)
    assert r.json()["done"]["title"] == "undo map clear (1 landmark removed)"
    assert _ids(api) == [5]


def _lm(i: int) -> Any:
    from store.models import LandmarkCreate

    return LandmarkCreate(id=i, x=float(i), y=0.0, z=2.5)


def _upd(**fields: float) -> Any:
    from store.models import LandmarkUpdate

    return LandmarkUpdate(**fields)

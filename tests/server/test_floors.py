"""Floors and versioned floor maps through the API: listing, bad input, versions, restore."""

from __future__ import annotations

from typing import Any

from tests.server.conftest import Api

FLOOR_1 = {"id": "1", "name": "First floor", "level": 1, "height": 4.2}
LM0 = [
    {"id": 1, "x": 0.0, "y": 0.0, "z": 2.5, "radio": "0013A20041000001"},
    {"id": 2, "x": 1.2, "y": 0.0, "z": 2.5},
]


def _floor(api: Api, floor_id: str) -> dict[str, Any]:
    r = api.client.get(f"/api/v1/floors/{floor_id}", headers=api.h("viewer"))
    assert r.status_code == 200, r.text
    body: dict[str, Any] = r.json()
    return body


def _setup(api: Api) -> None:
    h = api.h("admin")
    assert api.client.put("/api/v1/map", json={"landmarks": LM0}, headers=h).status_code == 200
    assert api.client.post("/api/v1/floors", json=FLOOR_1, headers=h).status_code == 201


def test_a_fresh_site_has_floor_0_and_floors_list_id_name_level(api: Api) -> None:
    _setup(api)
    floors = api.client.get("/api/v1/floors", headers=api.h("viewer")).json()
    assert [(f["id"], f["name"], f["level"]) for f in floors] == [
        ("0", "Floor 0", 0),
        ("1", "First floor", 1),
    ]
    assert floors[1]["height"] == 4.2 and floors[1]["landmarks"] == 0
    assert floors[0]["landmarks"] == 2 and len(floors[0]["hash"]) == 64
    m = api.client.get("/api/v1/floors/0/map", headers=api.h("viewer")).json()
    assert [lm["floor"] for lm in m["landmarks"]] == ["0", "0"]
    assert (m["version"], m["hash"]) == (floors[0]["version"], floors[0]["hash"])


def test_an_edit_bumps_version_and_hash_of_its_floor_only(api: Api) -> None:
    _setup(api)
    c, h = api.client, api.h("admin")
    v0, v1 = _floor(api, "0"), _floor(api, "1")
    r = c.post("/api/v1/landmarks", json={"id": 7, "x": 1, "y": 2, "z": 3, "floor": "1"}, headers=h)
    assert r.status_code == 201 and r.json()["floor"] == "1"
    assert _floor(api, "0")["version"] == v0["version"]  # floor 0 untouched
    a1 = _floor(api, "1")
    assert a1["version"] == v1["version"] + 1 and a1["hash"] != v1["hash"]
    # an edit that changes nothing is no new version; a real one is
    c.patch("/api/v1/landmarks/7", json={"x": 1.0}, headers=h)
    assert _floor(api, "1")["version"] == a1["version"]
    c.patch("/api/v1/landmarks/7", json={"x": 1.5}, headers=h)
    b1 = _floor(api, "1")
    assert b1["version"] == a1["version"] + 1 and b1["hash"] not in (a1["hash"], v1["hash"])
    # moving a landmark between floors is a new version of both
    c.patch("/api/v1/landmarks/7", json={"floor": "0"}, headers=h)
    assert _floor(api, "0")["version"] == v0["version"] + 1
    assert _floor(api, "1")["version"] == b1["version"] + 1
    assert _floor(api, "1")["hash"] == v1["hash"]  # empty again: the empty map's hash
    # each version is served as it was
    old = c.get("/api/v1/floors/1/map?version=" + str(b1["version"]), headers=h).json()
    assert [(lm["id"], lm["x"], lm["floor"]) for lm in old["landmarks"]] == [(7, 1.5, "1")]
    assert old["hash"] == b1["hash"] and not old["current"]
    versions = c.get("/api/v1/floors/1/map/versions", headers=h).json()
    assert [v["version"] for v in versions] == list(range(b1["version"] + 1, 0, -1))
    assert versions[0]["action"] == "update" and versions[0]["actor"].startswith("key:")


def test_restore_of_an_old_version_needs_confirmation_and_is_audited(api: Api) -> None:
    _setup(api)
    c, h = api.client, api.h("admin")
    v_start = _floor(api, "0")
    c.patch("/api/v1/landmarks/2", json={"x": 1.3}, headers=h)
    c.delete("/api/v1/landmarks/1", headers=h)
    assert [lm.id for lm in api.services.map.on_floor("0")] == [2]
    body = {"version": v_start["version"]}
    r = c.post("/api/v1/floors/0/map/restore", json=body, headers=h)
    assert r.status_code == 409 and "confirm" in r.json()["detail"]
    assert [lm.id for lm in api.services.map.on_floor("0")] == [2]  # nothing changed
    r = c.post("/api/v1/floors/0/map/restore?confirm=true", json=body, headers=h)
    assert r.status_code == 200, r.text
    restored = r.json()
    assert restored["hash"] == v_start["hash"] and restored["current"]
    assert restored["version"] == v_start["version"] + 3 and restored["action"] == "restore"
    lms = {lm.id: lm for lm in api.services.map.on_floor("0")}
    assert sorted(lms) == [1, 2] and lms[2].x == 1.2 and lms[1].radio == "0013A20041000001"
    audit = c.get("/api/v1/landmarks/audit?limit=1", headers=h).json()[0]
    assert audit["action"] == "restore" and audit["after"]["version"] == v_start["version"]
    # the restore is one step of its author's undo (a whole-floor step: confirmed)
    step = c.get("/api/v1/map/history", headers=h).json()["undo"]
    assert step["title"] == f"undo map restore of floor 0 to version {v_start['version']}"
    assert c.post("/api/v1/map/undo?confirm=true", headers=h).status_code == 200
    assert [lm.id for lm in api.services.map.on_floor("0")] == [2]
    # restoring what is current already changes nothing
    r = c.post("/api/v1/floors/0/map/restore?confirm=true", json={"version": 999}, headers=h)
    assert r.status_code == 404 and "999" in r.json()["detail"]


def test_bad_input_is_a_clear_4xx_and_nothing_is_stored(api: Api) -> None:
    _setup(api)
    c, h = api.client, api.h("admin")
    before = c.get("/api/v1/map", headers=h).json()
    versions = {f["id"]: f["version"] for f in c.get("/api/v1/floors", headers=h).json()}
    # a landmark on an unknown floor: create, move, import, floor import
    r = c.post("/api/v1/landmarks", json={"id": 9, "x": 0, "y": 0, "z": 2, "floor": "7"}, headers=h)
    assert r.status_code == 404 and "floor '7' does not exist" in r.json()["detail"]
    r = c.patch("/api/v1/landmarks/2", json={"floor": "7"}, headers=h)
    assert r.status_code == 404 and "landmark 2: floor '7'" in r.json()["detail"]
    doc = {"landmarks": [*LM0, {"id": 3, "x": 0, "y": 1, "z": 2, "floor": "B2"}]}
    r = c.put("/api/v1/map", json=doc, headers=h)
    assert r.status_code == 404 and "landmark 3: floor 'B2'" in r.json()["detail"]
    r = c.put("/api/v1/floors/1/map", json={"landmarks": [{"id": 5, "x": 0, "y": 0, "z": 2,
                                                          "floor": "0"}]}, headers=h)  # fmt: skip
    assert r.status_code == 409 and "names floor '0'" in r.json()["detail"]
    # two floors with one ID
    r = c.post("/api/v1/floors", json={**FLOOR_1, "name": "again"}, headers=h)
    assert r.status_code == 409 and "floor '1' already exists" in r.json()["detail"]
    r = c.post("/api/v1/floors", json={"id": "a b", "name": "x", "level": 2}, headers=h)
    assert r.status_code == 422
    # a landmark ID or radio of another floor, in a floor's map
    r = c.put("/api/v1/floors/1/map", json={"landmarks": [{"id": 2, "x": 0, "y": 0, "z": 2}]},
              headers=h)  # fmt: skip
    assert r.status_code == 409 and "landmark 2 hangs on floor '0'" in r.json()["detail"]
    lm = {"id": 5, "x": 0, "y": 0, "z": 2, "radio": "0013A20041000001"}
    r = c.put("/api/v1/floors/1/map", json={"landmarks": [lm]}, headers=h)
    assert r.status_code == 409 and "belongs to landmark 1 on floor '0'" in r.json()["detail"]
    # unknown floors in paths, deleting a floor with landmarks
    assert c.get("/api/v1/floors/9/map", headers=h).status_code == 404
    assert c.get("/api/v1/landmarks?floor=9", headers=h).status_code == 404
    r = c.delete("/api/v1/floors/0", headers=h)
    assert r.status_code == 409 and "still has 2 landmarks" in r.json()["detail"]
    assert c.get("/api/v1/map", headers=h).json() == before
    assert {f["id"]: f["version"] for f in c.get("/api/v1/floors", headers=h).json()} == versions


def test_a_floor_map_import_keeps_the_other_floors_and_is_undone_alone(api: Api) -> None:
    _setup(api)
    c, h = api.client, api.h("admin")
    lms = [{"id": 20, "x": 0, "y": 0, "z": 2.6}, {"id": 21, "x": 1, "y": 0, "z": 2.6}]
    r = c.put("/api/v1/floors/1/map", json={"landmarks": lms}, headers=h)
    assert r.status_code == 200 and r.json()["landmarks"] == 2
    assert [lm.id for lm in api.services.map.on_floor("1")] == [20, 21]
    assert [lm.id for lm in api.services.map.on_floor("0")] == [1, 2]
    assert c.get("/api/v1/landmarks?floor=1", headers=h).json()[0]["floor"] == "1"
    c.patch("/api/v1/landmarks/1", json={"x": 0.1}, headers=h)  # floor 0 edit
    assert c.post("/api/v1/map/undo", headers=h).status_code == 200  # that edit
    step = c.get("/api/v1/map/history", headers=h).json()["undo"]
    assert step["title"] == "undo map import of floor 1 (2 landmarks)"
    assert (step["landmarks_now"], step["landmarks_after"]) == (4, 2)
    assert c.post("/api/v1/map/undo?confirm=true", headers=h).status_code == 200
    assert api.services.map.on_floor("1") == [] and len(api.services.map.on_floor("0")) == 2
    # the CSV export names each landmark's floor and reads back the same
    csv_text = c.get("/api/v1/map?format=csv", headers=h).text
    assert csv_text.splitlines()[0].endswith(",floor") and csv_text.splitlines()[1].endswith(",0")


def test_a_floor_is_renamed_and_null_fields_are_refused(api: Api) -> None:
    c, h = api.client, api.h("admin")
    r = c.patch("/api/v1/floors/0", json={"name": "Ground", "height": -0.5}, headers=h)
    assert r.status_code == 200 and (r.json()["name"], r.json()["height"]) == ("Ground", -0.5)
    r = c.patch("/api/v1/floors/0", json={"name": "x", "height": None}, headers=h)
    assert r.status_code == 422 and "height" in r.json()["detail"]
    assert _floor(api, "0")["name"] == "Ground"

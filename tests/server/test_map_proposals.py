"""`/commissioning/map-proposals`: the robots' views propose map changes; staff accept
(an ordinary, audited, undoable map edit) or reject them. Fed here with a synthetic drive
under a grid whose landmark 17 hangs 5 cm from its map position (tests/survey/test_upkeep.py)."""

from __future__ import annotations

import numpy as np

from tests.server.conftest import Api
from tests.survey.test_upkeep import ceiling, drive

P = "/api/v1/commissioning/map-proposals"


def _drive_with_a_moved_landmark(api: Api, *, lock: bool = False) -> np.ndarray:
    """The grid as the map, landmark 17 moved 5 cm in truth; returns the truth."""
    ids, p = ceiling()
    landmarks = [{"id": i, "x": x, "y": y, "z": z, "locked": lock and i == 17}
                 for i, (x, y, z) in zip(ids, p.tolist(), strict=True)]  # fmt: skip
    h = api.h("admin")
    assert (
        api.client.put("/api/v1/map", json={"landmarks": landmarks}, headers=h).status_code == 200
    )
    truth = p.copy()
    truth[ids.index(17)] += (0.03, -0.04, 0.0)
    drive(api.services.upkeep, truth, ids, 120)
    return truth


def test_roles_and_bad_input(api: Api) -> None:
    c = api.client
    assert c.get(P).status_code == 401
    r = c.get(P, headers=api.h("viewer"))
    assert r.status_code == 200 and r.json() == {"frames": 0, "landmarks_seen": 0, "proposals": []}
    for role in ("viewer", "operator"):
        assert c.post(P + "/accept", json={}, headers=api.h(role)).status_code == 403
        assert (
            c.post(P + "/reject", json={"landmarks": [1]}, headers=api.h(role)).status_code == 403
        )
    h = api.h("admin")
    r = c.post(P + "/accept", json={"landmarks": [5]}, headers=h)
    assert r.status_code == 409 and "5 have no proposal" in r.json()["detail"], r.text
    r = c.post(P + "/reject", json={"landmarks": []}, headers=h)
    assert r.status_code == 422 and "landmarks" in r.json()["detail"]
    r = c.post(P + "/accept", json={"landmarks": ["a"]}, headers=h)
    assert r.status_code == 422
    r = c.post(P + "/accept", json={"landmarks": [-1]}, headers=h)
    assert r.status_code == 422
    r = c.post(P + "/accept", json={}, headers=h)  # nothing to accept: nothing done
    assert r.status_code == 200 and r.json()["done"] == []


def test_a_moved_landmark_is_proposed_accepted_audited_and_undone(api: Api) -> None:
    c, h = api.client, api.h("admin")
    truth = _drive_with_a_moved_landmark(api)
    st = c.get(P, headers=api.h("viewer")).json()
    moved = [p for p in st["proposals"] if p["kind"] == "moved"]
    assert [p["landmark_id"] for p in moved] == [17], st
    p = moved[0]
    assert not p["locked"] and p["views"] >= 10 and p["statistic"] > 30
    new = np.array([p["proposed"][k] for k in "xyz"])
    assert np.linalg.norm(new - truth[7]) < 0.005
    # a bad ID among good ones: nothing is written
    before = c.get("/api/v1/landmarks/17", headers=h).json()
    r = c.post(P + "/accept", json={"landmarks": [17, 99]}, headers=h)
    assert r.status_code == 409 and "99" in r.json()["detail"]
    assert c.get("/api/v1/landmarks/17", headers=h).json() == before
    r = c.post(P + "/accept", json={"landmarks": [17]}, headers=h)
    assert r.status_code == 200 and r.json()["done"] == [17], r.text
    assert 17 not in [q["landmark_id"] for q in r.json()["status"]["proposals"]]
    lm = c.get("/api/v1/landmarks/17", headers=h).json()
    np.testing.assert_allclose([lm["x"], lm["y"], lm["z"]], new, atol=1e-9)
    audit = c.get("/api/v1/landmarks/audit", headers=h).json()[0]  # newest first
    assert audit["action"] == "update" and audit["landmark_id"] == 17
    assert audit["actor"].endswith(" (map upkeep)") and audit["before"]["x"] == before["x"]
    # accepting is an ordinary edit: undo puts the old position back
    r = c.post("/api/v1/map/undo", headers=h)
    assert r.status_code == 200, r.text
    lm = c.get("/api/v1/landmarks/17", headers=h).json()
    assert (lm["x"], lm["y"], lm["z"]) == (before["x"], before["y"], before["z"])


def test_locked_landmarks_are_flagged_and_rejecting_drops_the_evidence(api: Api) -> None:
    c, h = api.client, api.h("admin")
    _drive_with_a_moved_landmark(api, lock=True)
    st = c.get(P, headers=h).json()
    (p,) = [q for q in st["proposals"] if q["kind"] == "moved"]
    assert p["landmark_id"] == 17 and p["locked"]
    # accepting every proposal leaves the locked one; naming it accepts it
    r = c.post(P + "/accept", json={}, headers=h)
    assert 17 not in r.json()["done"]
    assert c.get("/api/v1/landmarks/17", headers=h).json()["x"] == p["old"]["x"]
    r = c.post(P + "/reject", json={"landmarks": [17]}, headers=h)
    assert r.status_code == 200 and r.json()["done"] == [17]
    assert 17 not in [q["landmark_id"] for q in r.json()["status"]["proposals"]]
    assert c.get("/api/v1/landmarks/17", headers=h).json()["x"] == p["old"]["x"]
    events = c.get("/api/v1/events", headers=h).json()
    assert any("rejected the map proposals of 17" in e["message"] for e in events), events

"""`/leds`: pinning landmarks lit under the schedule, and what the schedule lights and why."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from tests.server.conftest import Api, start_api


@pytest.fixture(scope="module")
def scheduled(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Api]:
    """The virtual site's world and radio under the LED schedule, without robots (so the
    schedule lights nothing but what is pinned); one site for the module's tests."""
    yield from start_api(tmp_path_factory.mktemp("leds"), led_policy="scheduled", sim_robots=False)


def test_a_pinned_landmark_is_lit_with_its_reason_until_unpinned(scheduled: Api) -> None:
    api = scheduled
    lid = sorted(api.services.leds.controlled)[0]
    r = api.client.post(
        "/api/v1/leds/pin",
        json={"landmarks": [lid], "reason": "survey", "duration_s": 60},
        headers=api.h("operator"),
    )
    assert r.status_code == 200, r.text
    (pin,) = r.json()
    assert pin["landmark_id"] == lid and pin["reason"] == "survey"
    assert 59.0 < pin["remaining_s"] <= 60.0
    st = api.wait_for(
        "/api/v1/leds/schedule", lambda s: {"landmark_id": lid, "reason": "pinned: survey"}
        in s["lit"], 10.0, role="viewer",
    )  # fmt: skip
    assert st["policy"] == "scheduled"
    assert [p["landmark_id"] for p in st["pinned"]] == [lid]
    api.wait_for("/api/v1/radio", lambda s: lid in s["lit"], 10.0)
    r = api.client.delete(f"/api/v1/leds/pin/{lid}", headers=api.h("operator"))
    assert r.status_code == 200 and r.json() == []
    api.wait_for("/api/v1/radio", lambda s: lid not in s["lit"], 10.0)
    r = api.client.delete(f"/api/v1/leds/pin/{lid}", headers=api.h("operator"))
    assert r.status_code == 404 and str(lid) in r.text


def test_pins_are_checked_and_need_the_operator_role(scheduled: Api) -> None:
    api = scheduled
    body = {"landmarks": [999999], "reason": "check", "duration_s": 10}
    r = api.client.post("/api/v1/leds/pin", json=body, headers=api.h("operator"))
    assert r.status_code == 404 and "999999" in r.text
    body["landmarks"] = [sorted(api.services.leds.controlled)[0]]
    r = api.client.post("/api/v1/leds/pin", json=body, headers=api.h("viewer"))
    assert r.status_code == 403
    r = api.client.post(
        "/api/v1/leds/pin", json={**body, "duration_s": 7200}, headers=api.h("operator")
    )
    assert r.status_code == 422 and "duration_s" in r.text


def test_with_all_lit_there_is_nothing_to_pin(tmp_path: Path) -> None:
    for api in start_api(tmp_path, led_policy="all_lit", sim_robots=False):
        lid = sorted(api.services.leds.controlled)[0]
        body = {"landmarks": [lid], "reason": "check", "duration_s": 10}
        r = api.client.post("/api/v1/leds/pin", json=body, headers=api.h("operator"))
        assert r.status_code == 409 and "all_lit" in r.text
        st = api.client.get("/api/v1/leds/schedule", headers=api.h("viewer")).json()
        assert st == {"policy": "all_lit", "lit": [], "pinned": [], "lit_fraction": 1.0}


def test_what_the_survey_and_the_wizard_keep_lit_is_pinned_until_they_release_it(
    scheduled: Api,
) -> None:
    """`LedsAndRadio.keep_lit` / `release`, as the survey (the whole ceiling) and the wizard
    (the landmark it measures) use them: pins of the schedule under their own reason, lit
    through the radio, and released by reason only."""
    api = scheduled
    leds = api.services.leds
    a, b, c = sorted(leds.controlled)[1:4]
    leds.keep_lit([a, b], "survey", 60.0)
    leds.keep_lit([c], "wizard", 60.0)
    api.wait_for("/api/v1/radio", lambda s: {a, b, c} <= set(s["lit"]), 10.0)
    st = api.client.get("/api/v1/leds/schedule", headers=api.h("viewer")).json()
    reasons = {p["landmark_id"]: p["reason"] for p in st["pinned"]}
    assert reasons == {a: "survey", b: "survey", c: "wizard"}
    leds.release("survey")
    api.wait_for("/api/v1/radio", lambda s: not {a, b} & set(s["lit"]), 10.0)
    st = api.client.get("/api/v1/leds/schedule", headers=api.h("viewer")).json()
    assert [(p["landmark_id"], p["reason"]) for p in st["pinned"]] == [(c, "wizard")]
    leds.release("wizard")
    api.wait_for("/api/v1/radio", lambda s: c not in s["lit"], 10.0)

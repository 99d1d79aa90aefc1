"""Cells replaced: the battery estimate of a landmark starts over after fresh cells."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from tests.server.conftest import LM, Api


def test_cells_replaced_restarts_the_battery_trend_and_needs_confirmation(api: Api) -> None:
    c, services = api.client, api.services
    assert c.post("/api/v1/landmarks", json=LM, headers=api.h("admin")).status_code == 201
    start = datetime.now(UTC) - timedelta(days=30)
    for day in range(30):  # 30 days falling 10 mV a day: about 40 days left
        services.log.add_battery(11, 2900 - 10 * day, t=start + timedelta(days=day))
    before = c.get("/api/v1/landmarks/11/battery", headers=api.h("viewer")).json()
    assert len(before["history"]) == 30 and before["days_left"] is not None
    path = "/api/v1/landmarks/11/cells-replaced"
    assert c.post(path, headers=api.h("viewer")).status_code == 403
    r = c.post(path, headers=api.h("operator"))
    assert r.status_code == 409 and "confirm=true" in r.text  # nothing done
    assert services.log.last_event("cells_replaced", landmark_id=11) is None
    assert c.post("/api/v1/landmarks/99/cells-replaced?confirm=true",
                  headers=api.h("operator")).status_code == 404  # fmt: skip
    r = c.post(f"{path}?confirm=true", headers=api.h("operator"))
    assert r.status_code == 200, r.text
    done = r.json()
    # no radio on this site: nothing read since the swap, and it says why
    assert done["read"] is False and "no radio" in done["why_not"]
    assert done["battery"]["supply_mv"] is None and done["battery"]["history"] == []
    ev = c.get("/api/v1/events?kind=cells_replaced", headers=api.h("viewer")).json()
    assert ev[0]["landmark_id"] == 11 and ev[0]["data"]["actor"].startswith("key:")
    services.log.add_battery(11, 3150)  # the first reading of the new cells
    after = c.get("/api/v1/landmarks/11/battery", headers=api.h("viewer")).json()
    assert [h["supply_mv"] for h in after["history"]] == [3150]
    assert after["days_left"] is None  # one reading: no trend yet
    assert len(services.log.battery_history(11)) == 31  # the old readings are kept

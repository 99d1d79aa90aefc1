"""Keeping the map true on the live demo site: the robots' poses reach the map upkeep through
the pose bus with their frames' spots, and a landmark shifted 5 cm in the map (the map is
wrong, the landmark hangs where it did) is proposed back to where it hangs."""

from __future__ import annotations

from collections.abc import Iterator

import numpy as np
import pytest

from store.models import LandmarkUpdate
from tests.server.conftest import Api, start_api
from tests.web.conftest import landmark_always_in_view

P = "/api/v1/commissioning/map-proposals"


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Api]:
    yield from start_api(tmp_path_factory.mktemp("upkeep"), seed=5)


@pytest.mark.slow
def test_a_landmark_wrong_in_the_map_is_proposed_where_it_hangs(live: Api) -> None:
    services = live.services
    assert services.virtual_site is not None
    for (
        name
    ) in services.virtual_site.robot_names:  # an operator's hint: no identification to wait for
        x, y, th = services.virtual_site.true_pose(name)
        hint = {"x": x, "y": y, "theta": th}
        r = live.client.post(
            f"/api/v1/robots/{name}/relocalize", json=hint, headers=live.h("operator")
        )
        assert r.status_code == 202, r.text
    # evidence on the landmark before the map goes wrong: it is then re-centred on the wrong
    # position, and points back at once
    live.wait_for(P, lambda st: st["frames"] >= 15, 90.0, role="viewer", every_s=0.5)
    lid = landmark_always_in_view(services, "r2")
    truth = services.virtual_site.world.landmarks[lid].p_true
    lm = services.map.get(lid)
    services.map.update(lid, LandmarkUpdate(x=lm.x + 0.04, y=lm.y - 0.03), actor="test")

    def proposed(st: dict[str, object]) -> bool:
        props = st["proposals"]
        assert isinstance(props, list)
        return any(p["landmark_id"] == lid and p["kind"] == "moved" for p in props)

    st = live.wait_for(P, proposed, 60.0, role="viewer", every_s=0.5)
    (p,) = [q for q in st["proposals"] if q["landmark_id"] == lid]
    new = np.array([p["proposed"][k] for k in "xyz"])
    assert np.linalg.norm(new[:2] - truth[:2]) < 0.01, (new, truth)
    assert [q["landmark_id"] for q in st["proposals"] if q["kind"] == "moved"] == [lid]
    r = live.client.post(P + "/accept", json={"landmarks": [lid]}, headers=live.h("admin"))
    assert r.status_code == 200 and r.json()["done"] == [lid]
    assert np.linalg.norm(np.array([services.map.get(lid).x, services.map.get(lid).y])
                          - truth[:2]) < 0.01  # fmt: skip

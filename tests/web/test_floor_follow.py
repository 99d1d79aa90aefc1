"""The viewer follows the floor shown: its landmarks' extent and ceiling, its floor plan
and its zones (the site's services, no live site; a real SQLite file and data folder)."""

from __future__ import annotations

from pathlib import Path

import cv2
import numpy as np

from store.floorplan import Placement
from store.models import FloorCreate, LandmarkCreate
from tests.server.conftest import start_api
from web.viewer import Viewer


def _png(w: int, h: int) -> bytes:
    ok, buf = cv2.imencode(".png", np.full((h, w, 3), 200, np.uint8))
    assert ok
    return buf.tobytes()


def test_switching_floors_switches_extent_ceiling_plan_and_zones(tmp_path: Path) -> None:
    for api in start_api(tmp_path, site_enabled=False):
        services = api.services
        services.floors.create(FloorCreate(id="1", name="Offices", level=1, height=4.0))
        for lid, x, floor, z in ((1, 0.0, "0", 2.5), (2, 4.0, "0", 2.5), (10, 20.0, "1", 3.1),
                                 (11, 30.0, "1", 3.1)):  # fmt: skip
            services.map.create(LandmarkCreate(id=lid, x=x, y=0.0, z=z, floor=floor), actor="t")
        place = Placement((0, 0), (0, 0), (100, 0), (10, 0))
        services.floorplans.of("1").put(_png(100, 50), "image/png", place)
        assert services.floorplans.of("0").info() is None  # each floor its own plan
        services.zones.create("lab", [(20, 0), (25, 0), (25, 5)], floor="1")
        services.zones.create("lobby", [(0, 0), (1, 0), (1, 1)], floor="0")
        viewer = Viewer()
        viewer.start(services)
        viewer._stop.set()  # this test ticks itself, not the update thread meanwhile
        assert viewer._thread is not None
        viewer._thread.join(timeout=10)
        try:
            assert viewer.scene is not None and viewer.zones is not None
            assert viewer.floorplan is not None and viewer.floorplan.info is None
            assert viewer.scene.ceiling_z == 2.8  # both floors: the median of 2.5, 3.1
            viewer.site.show_floor("1")
            viewer._tick(True, True)
            assert viewer.scene.ceiling_z == 3.1
            assert viewer.scene.bounds[:2] == (18.0, 32.0)  # its landmarks and 2 m around
            assert viewer.scene.landmark_ids() == [10, 11]
            assert viewer.floorplan.info is not None and viewer.floorplan.info.width_m == 10.0
            assert [z.name for z, _ in viewer.zones.shown.values()] == ["lab"]
            viewer.site.show_floor("0")
            viewer._tick(True, True)
            assert viewer.scene.ceiling_z == 2.5 and viewer.floorplan.info is None
            assert [z.name for z, _ in viewer.zones.shown.values()] == ["lobby"]
        finally:
            viewer.stop()

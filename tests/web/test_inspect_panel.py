"""Click-to-inspect through the `ViewerSite` protocol: a landmark's or robot's details, and
"cells replaced" behind its confirmation (operators)."""

from __future__ import annotations

from dataclasses import replace
from pathlib import Path

import pytest
import viser

from tests.web.memsite import grid_site
from web.panels.inspect import InspectPanel, LastUse
from web.roles import Session


def test_a_landmark_and_a_robot_are_described_and_cells_replaced_needs_a_tick(
    server: viser.ViserServer,
) -> None:
    site = grid_site()
    site.map[15] = replace(site.map[15], radio="0013A2004100000F", supply_mv=2480, percent=40.0,
                           days_left=55.0, model_days=80.0, lit=True, lit_reason="view r1",
                           duty=0.25, sigma_m=0.0012)  # fmt: skip
    clock = [1000.0]
    last = LastUse(clock=lambda: clock[0])
    last.add(site.robots())
    clock[0] = 1042.0
    notes: list[str] = []
    panel = InspectPanel(server.gui, site, Session("operator", "key:2"), last,
                         lambda t, b: notes.append(b))  # fmt: skip
    text = panel.select("landmark", "15")
    users = [r.name for r in site.robots() if r.pose is not None and 15 in r.pose.landmark_ids]
    assert users, "r1 sees landmark 15 in the grid site"
    assert "**Landmark 15**" in text and "\u00b11.2 mm" in text and "0013A2004100000F" in text
    assert "battery 2.48 V (40 %): 55 d by the trend, 80 d at its duty" in text
    assert "LED on (view r1), lit 25 % of the time" in text
    assert f"used now by {', '.join(users)}" in text and "last used by" in text
    assert panel.gui_cells is not None and panel.gui_cells.visible
    assert not panel.cells_replaced() and "tick" in notes[-1] and site.cells == []
    assert panel.gui_sure is not None
    panel.gui_sure.value = True  # type: ignore[misc]
    assert panel.cells_replaced() and site.cells == [(15, "key:2")]
    assert "battery estimate starts over; reads 3.15 V" in notes[-1]
    assert "battery 3.15 V (100 %): no trend yet" in panel.refresh()
    robot = panel.select("robot", "r1")
    assert robot.startswith("**Robot r1**") and "at (1.50, 1.00) m" in robot
    assert "in zone" not in robot  # the site keeps no zones
    assert not panel.gui_cells.visible  # not for a robot
    assert "not in the map" in panel.select("landmark", "999")


def test_a_robot_says_which_zones_it_is_in(server: viser.ViserServer, tmp_path: Path) -> None:
    from store.db import make_engine, migrate
    from store.zones import ZoneStore

    engine = make_engine(f"sqlite:///{tmp_path / 'irloc.db'}")
    migrate(engine)
    site = grid_site()
    site.zone_store = ZoneStore(engine)
    site.zone_store.create("dock", [(1, 0), (2, 0), (2, 2), (1, 2)])  # r1 at (1.5, 1)
    site.zone_store.create("bay", [(5, 5), (6, 5), (6, 6)])
    panel = InspectPanel(server.gui, site, Session("viewer", "key:3"), LastUse(),
                         lambda t, b: None)  # fmt: skip
    assert "- in zone dock" in panel.select("robot", "r1")
    assert "in zone" not in panel.select("robot", "r2")  # at (0.5, 0.2)
    engine.dispose()


@pytest.mark.parametrize("role", ["viewer"])
def test_a_viewer_inspects_but_has_no_cells_replaced(server: viser.ViserServer, role: str) -> None:
    panel = InspectPanel(server.gui, grid_site(), Session(role, "key:3"), LastUse(),
                         lambda t, b: None)  # fmt: skip
    assert panel.gui_cells is None and not panel.cells_replaced()
    assert "**Landmark 10**" in panel.select("landmark", "10")

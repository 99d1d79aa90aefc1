"""Zones in the viewer: the shared layer draws the floor's zones, admins make, edit and
delete them through the same store as `/api/v1/zones` (a real SQLite file)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import viser

from store.db import make_engine, migrate
from store.zones import ZoneStore
from web.panels.zones import ZonesPanel, floor_point, parse_points, points_text
from web.roles import Session
from web.zones_view import DWELL_ZONE_COLOR, ZONE_COLOR, ZonesLayer, ring_segments


@pytest.fixture
def store(tmp_path: Path) -> Iterator[ZoneStore]:
    engine = make_engine(f"sqlite:///{tmp_path / 'irloc.db'}")
    migrate(engine)
    yield ZoneStore(engine)
    engine.dispose()


def test_points_are_parsed_and_a_click_meets_the_floor() -> None:
    assert parse_points("0, 0; 2,0\n2 1.5") == [(0.0, 0.0), (2.0, 0.0), (2.0, 1.5)]
    with pytest.raises(ValueError, match="point 2: '3' is not 'x, y'"):
        parse_points("0,0; 3")
    assert points_text([(1.0, 2.0), (3.5, 2.0)]) == "1.00, 2.00; 3.50, 2.00"
    # from 10 m above (1, 2) looking down at 45 degrees along +x: meets the floor at x = 11
    assert floor_point((1.0, 2.0, 10.0), (1.0, 0.0, -1.0)) == pytest.approx((11.0, 2.0))
    assert floor_point((0.0, 0.0, 10.0), (1.0, 0.0, 0.5)) is None  # looks up
    seg = ring_segments([(0, 0), (2, 0), (2, 1)])
    assert seg.shape == (3, 2, 3) and np.allclose(seg[-1, 1, :2], (0, 0))  # closed


def test_admin_makes_edits_and_deletes_a_zone_and_the_layer_follows(
    server: viser.ViserServer, store: ZoneStore
) -> None:
    notes: list[str] = []
    floor: list[str | None] = [None]
    panel = ZonesPanel(server, store, Session("admin", "key:1"), lambda: floor[0],
                       lambda t, b: notes.append(b))  # fmt: skip
    layer = ZonesLayer(server.scene, store)
    assert layer.refresh(None) and layer.shown == {}
    panel.gui_name.value = "dock"  # type: ignore[misc]
    for origin in ((0.0, 0.0), (2.0, 0.0), (2.0, 2.0)):  # clicked straight down
        panel.add_corner((*origin, 20.0), (0.0, 0.0, -1.0))
    assert panel.gui_points.value == "0.00, 0.00; 2.00, 0.00; 2.00, 2.00"
    z = panel.create()
    assert z is not None and z.polygon == [[0, 0], [2, 0], [2, 2]] and z.dwell_s is None
    assert panel.create() is None and "exists already" in notes[-1]  # the name is taken
    panel.refresh()
    assert "**dock** (3 corners)" in panel.gui_list.content
    assert layer.refresh(None) and layer.shown[z.id or 0][1] == ZONE_COLOR
    assert not layer.refresh(None)  # nothing changed: nothing sent
    panel.gui_zone.value = f"{z.id}: dock"  # type: ignore[misc]
    panel._load()
    panel.gui_dwell.value = 30.0  # type: ignore[misc]
    panel.gui_points.value = "0,0; 3,0; 3,3; 0,3"  # type: ignore[misc]
    saved = panel.save()
    assert saved is not None and saved.dwell_s == 30.0 and len(saved.polygon) == 4
    assert layer.refresh(None) and layer.shown[z.id or 0][1] == DWELL_ZONE_COLOR
    panel.gui_points.value = "0,0; 1,1; 2,2"  # type: ignore[misc]
    assert panel.save() is None and "no area" in notes[-1]  # nothing stored
    assert len(store.get(z.id or 0).polygon) == 4
    assert not panel.delete() and "tick" in notes[-1]
    panel.gui_sure.value = True  # type: ignore[misc]
    assert panel.delete() and store.list() == []
    assert layer.refresh(None) and layer.shown == {}


def test_zones_of_another_floor_are_not_drawn_and_viewers_only_read(
    server: viser.ViserServer, store: ZoneStore
) -> None:
    store.create("lobby", [(0, 0), (1, 0), (1, 1)], floor="0")
    store.create("lab", [(0, 0), (1, 0), (1, 1)], floor="1")
    store.create("shaft", [(5, 5), (6, 5), (6, 6)])  # every floor
    layer = ZonesLayer(server.scene, store)
    layer.refresh("1")
    assert sorted(z.name for z, _ in layer.shown.values()) == ["lab", "shaft"]
    layer.refresh(None)
    assert len(layer.shown) == 3
    panel = ZonesPanel(server, store, Session("operator", "key:2"), lambda: "0",
                       lambda t, b: None)  # fmt: skip
    assert not panel.editing and not hasattr(panel, "gui_create")
    assert "**lobby**" in panel.gui_list.content and "lab" not in panel.gui_list.content


def test_a_status_line_clears_a_while_after_its_action(server: viser.ViserServer) -> None:
    from web.status_line import StatusLine

    now = [100.0]
    line = StatusLine(server.gui.add_markdown(""), ttl_s=20.0, clock=lambda: now[0])
    line.say("zone **dock** saved")
    now[0] = 119.0
    assert not line.refresh() and line.handle.content == "zone **dock** saved"
    now[0] = 120.5
    assert line.refresh() and line.handle.content == ""
    assert not line.refresh()  # nothing to clear

"""The floor plan in the scene and its admin panel, on a real viser server (no browser)."""

from __future__ import annotations

import math
from pathlib import Path

import cv2
import numpy as np
import pytest
import viser

from store.floorplan import FloorPlanStore, Placement
from web.floorplan_view import FloorPlanLayer, FloorPlanPanel, floorplan_pixels


def _png(w: int, h: int) -> bytes:
    img = np.zeros((h, w, 3), np.uint8)
    img[:10, :] = (0, 0, 255)  # top rows red (BGR)
    ok, buf = cv2.imencode(".png", img)
    assert ok
    return bytes(buf.tobytes())


def test_the_layer_follows_the_store(server: viser.ViserServer, tmp_path: Path) -> None:
    store = FloorPlanStore(tmp_path)
    layer = FloorPlanLayer(server.scene, store)
    assert layer.refresh() and layer.info is None
    store.put(_png(400, 200), "image/png", Placement((0, 0), (0, 0), (0, 200), (-5, 0)))
    assert layer.refresh() and not layer.refresh()  # redrawn once per change
    node = server.scene.get_handle_by_name("/floorplan")
    assert node is not None
    # 200 px along the image's column to 5 m west: 2.5 cm a pixel, turned by -90 degrees
    assert layer.info is not None and layer.info.rotation_rad == pytest.approx(-math.pi / 2)
    np.testing.assert_allclose(node.position[:2], layer.info.center_m)
    np.testing.assert_allclose(node.wxyz, [math.cos(-math.pi / 4), 0, 0, math.sin(-math.pi / 4)])
    store.delete()
    assert layer.refresh() and server.scene.get_handle_by_name("/floorplan") is None


def test_pixels_go_bottom_row_first_and_are_bounded() -> None:
    px = floorplan_pixels(_png(3000, 1000), max_px=1500)
    assert px.shape == (500, 1500, 3)
    np.testing.assert_array_equal(px[-1, 0], [255, 0, 0])  # the image's top row, RGB, last


def test_the_panel_stretches_a_plan_across_the_site(
    server: viser.ViserServer, tmp_path: Path
) -> None:
    notes: list[str] = []
    store = FloorPlanStore(tmp_path)
    panel = FloorPlanPanel(server.gui, store, (-2.0, 16.0, -1.0, 9.0), lambda t, b: notes.append(b))
    info = panel.upload("hall.png", _png(900, 500))
    assert info is not None and info.metres_per_px == pytest.approx(0.02)
    assert info.center_m == pytest.approx((7.0, 4.0))  # top edge on the north edge y = 9
    assert panel.upload("hall.gif", b"GIF89a") is None and "hall.gif" in notes[-1]
    assert store.info() == info  # the refused file changed nothing

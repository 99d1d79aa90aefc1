"""The lens calibration panel on a real viser server (no browser), on OpenCV's photos."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest
import viser

from tests.web.memsite import grid_site
from web.panels.calibration import CalibrationPanel
from web.roles import Session

PHOTOS = Path(__file__).parents[1] / "data" / "chessboard"


def _panel(server: viser.ViserServer, role: str) -> tuple[CalibrationPanel, list[str]]:
    notes: list[str] = []
    site = grid_site()
    panel = CalibrationPanel(
        server.gui, site, Session(role, f"{role}:test"), lambda t, b: notes.append(b)
    )
    return panel, notes


@pytest.mark.slow
def test_calibrates_uploaded_photos_and_stores_keeping_the_mounting(
    server: viser.ViserServer,
) -> None:
    panel, notes = _panel(server, "admin")
    site = panel.site
    mount = np.array(site.robots()[0].camera.T_body_camera)
    for p in sorted(PHOTOS.glob("*.jpg"))[:8]:
        panel.add_photo(p.name, p.read_bytes())
    text = panel.calibrate()
    assert panel.result is not None and "RMS" in text.upper()
    assert 0.1 < panel.result.rms_px < 1.0
    assert not panel.gui_store.disabled
    np.testing.assert_allclose(panel.result.camera.T_body_camera, mount)
    panel.store()
    assert site.stored_cameras == [(panel.gui_robot.value, "admin:test")]  # type: ignore[attr-defined]
    assert any("stored with robot" in n for n in notes)


def test_bad_photo_names_the_file_and_keeps_nothing(server: viser.ViserServer) -> None:
    panel, _ = _panel(server, "admin")
    panel.add_photo("notes.txt", b"not an image")
    text = panel.calibrate()
    assert "notes.txt" in text and panel.result is None and panel.gui_store.disabled
    panel.store()
    assert panel.site.stored_cameras == []  # type: ignore[attr-defined]


def test_viewer_cannot_store(server: viser.ViserServer) -> None:
    panel, notes = _panel(server, "viewer")
    for p in sorted(PHOTOS.glob("*.jpg"))[:6]:
        panel.add_photo(p.name, p.read_bytes())
    panel.calibrate()
    assert panel.gui_store.disabled
    panel.store()
    assert panel.site.stored_cameras == []  # type: ignore[attr-defined]
    assert any("may not change robots" in n for n in notes)

"""`/recordings`: listed, downloaded as a zip and deleted through the API, kept within the
retention bounds; a cancelled survey's recording is removed."""

from __future__ import annotations

import io
import json
import time
import zipfile
from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from store.recording_catalog import RecordingCatalog, write_meta
from tests.server.conftest import Api, start_api

R = "/api/v1/recordings"


@pytest.fixture(scope="module")
def live(tmp_path_factory: pytest.TempPathFactory) -> Iterator[Api]:
    yield from start_api(tmp_path_factory.mktemp("recordings"), seed=3)


def test_record_list_download_delete(live: Api) -> None:
    c, op, admin = live.client, live.h("operator"), live.h("admin")
    r = c.post("/api/v1/robots/r1/recording/start", headers=op)
    assert r.status_code == 200, r.text
    name = r.json()["name"]
    listed = c.get(R, headers=live.h("viewer")).json()
    assert listed[0]["name"] == name and listed[0]["live"] and listed[0]["trigger"] == "manual"
    assert c.get(f"{R}/{name}/download", headers=op).status_code == 409  # still written
    deadline = time.monotonic() + 60  # a few frames, however loaded the machine
    while c.get(f"{R}/{name}", headers=op).json()["frames"] <= 5 and time.monotonic() < deadline:
        time.sleep(0.2)
    assert c.post("/api/v1/robots/r1/recording/stop", headers=op).json()["name"] == name
    info = c.get(f"{R}/{name}", headers=live.h("viewer")).json()
    assert not info["live"] and info["frames"] > 5 and info["size_bytes"] > 10_000, info
    assert c.get(f"{R}/{name}/download", headers=live.h("viewer")).status_code == 403
    z = c.get(f"{R}/{name}/download", headers=op)
    assert z.status_code == 200 and z.headers["content-type"] == "application/zip"
    files = zipfile.ZipFile(io.BytesIO(z.content)).namelist()
    assert f"{name}/cam0/data.csv" in files and f"{name}/map.json" in files
    assert sum(f.endswith(".png") for f in files) == info["frames"]
    assert c.get(f"{R}?robot=r2", headers=op).json() == []
    r = c.delete(f"{R}/{name}", headers=admin)
    assert r.status_code == 409 and "confirm=true" in r.json()["detail"]
    assert c.delete(f"{R}/{name}?confirm=true", headers=op).status_code == 403
    assert c.delete(f"{R}/{name}?confirm=true", headers=admin).status_code == 204
    r = c.get(f"{R}/{name}", headers=op)
    assert r.status_code == 404 and name in r.json()["detail"]
    assert c.get(f"{R}/..%2Fetc", headers=op).status_code in (404, 422)


def test_a_cancelled_survey_leaves_no_recording(live: Api) -> None:
    c, h = live.client, live.h("admin")
    for lid in (107, 122):
        c.patch(f"/api/v1/landmarks/{lid}", json={"locked": True}, headers=h)
    r = c.post("/api/v1/commissioning/survey/start", json={"robot": "r2"}, headers=h)
    assert r.status_code == 200, r.text
    folder = Path(r.json()["recording"])
    assert folder.is_dir()
    assert [x["trigger"] for x in c.get(R, headers=h).json()] == ["survey"]
    assert c.post("/api/v1/commissioning/survey/cancel", headers=h).status_code == 200
    assert not folder.exists() and c.get(R, headers=h).json() == []


def _fake(root: Path, name: str, started: datetime, size: int) -> None:
    folder = root / name
    write_meta(folder, name.split("-")[0], "manual", started)
    (folder / "blob").write_bytes(b"x" * size)


def test_retention_removes_the_oldest_beyond_age_and_size(tmp_path: Path) -> None:
    now = datetime(2026, 12, 7, 12, tzinfo=UTC)
    live = tmp_path / "r9-20261207T115900"
    for k, days in enumerate((40, 20, 10, 2, 1)):
        _fake(tmp_path, f"r{k}-x", now - timedelta(days=days), 1000)
    _fake(tmp_path, live.name, now - timedelta(days=90), 1000)  # being written: kept
    cat = RecordingCatalog(tmp_path, lambda: {live}, keep_days=30, max_total_bytes=3500)
    gone = cat.prune(now)
    assert gone == ["r0-x", "r1-x", "r2-x"]  # 40 days; then the oldest until 3 fit
    assert sorted(r.name for r in cat.list()) == sorted(["r3-x", "r4-x", live.name])
    meta = json.loads((live / "irloc_recording.json").read_text())
    assert meta["trigger"] == "manual"


def test_the_viewer_panel_records_lists_and_deletes_only_when_ticked(live: Api) -> None:
    import viser

    from web.panels.recordings import RecordingsPanel
    from web.roles import Session

    notes: list[str] = []
    server = viser.ViserServer("127.0.0.1", 0, verbose=False)
    try:
        panel = RecordingsPanel(server.gui, live.services.recordings, Session("admin", "web:key:1"),
                                lambda: "r3", lambda t, b: notes.append(b))  # fmt: skip
        name = panel.start()
        assert (
            name is not None
            and name.startswith("r3-")
            and "(recording...)" in panel.gui_list.content
        )
        assert panel.stop() == name
        assert f"/viewer/recordings/{name}.zip" in panel.gui_list.content
        assert panel.gui_name is not None and panel.gui_sure is not None
        panel.gui_name.value = name  # type: ignore[misc]
        assert not panel.delete() and "tick" in notes[-1]  # not confirmed: kept
        assert (live.services.settings.recordings_dir / name).is_dir()
        panel.gui_sure.value = True  # type: ignore[misc]
        assert panel.delete() and not (live.services.settings.recordings_dir / name).exists()
        box = panel.save_black_box()  # the viewer's button, as POST /robots/r3/black-box
        assert box is not None and box.startswith("r3-") and box.endswith("blackbox-operator")
        assert f"`{box}` black_box_operator" in panel.gui_list.content
    finally:
        server.stop()

"""Graceful shutdown: every LED left lit, the database closed cleanly."""

from __future__ import annotations

from pathlib import Path

import pytest

from tests.server.conftest import start_api

pytestmark = pytest.mark.slow


def test_shutdown_leaves_every_led_on_and_closes_the_database(tmp_path: Path) -> None:
    for api in start_api(tmp_path, scenario="paper_testbed"):
        world = api.services.virtual_site.world
        ids = sorted(world.landmarks)
        r = api.client.post(f"/api/v1/landmarks/{ids[0]}/led", json={"on": False},
                            headers=api.h("operator"))  # fmt: skip
        assert r.status_code == 200, r.text  # (the robot's sweep may switch it again)
    # the TestClient has run the lifespan's shutdown
    assert sorted(world.lit_ids()) == ids
    # the last connection closed cleanly: SQLite checkpointed and removed its WAL file
    assert (tmp_path / "irloc.db").exists() and not (tmp_path / "irloc.db-wal").exists()

"""The viewer's floor selector over the server's services (web/adapter.py, SiteAdapter):
the scene shows one floor's landmarks and robots, or every floor's."""

from __future__ import annotations

from pathlib import Path

import pytest

from store.errors import NotFoundError
from store.models import FloorCreate, LandmarkCreate
from tests.server.conftest import start_api
from web.adapter import SiteAdapter


def test_the_adapter_shows_one_floor_or_every_floor(tmp_path: Path) -> None:
    for api in start_api(tmp_path, site_enabled=False):
        services = api.services
        services.floors.create(FloorCreate(id="1", name="Offices", level=1, height=4.0))
        for lid, floor in ((1, "0"), (2, "0"), (10, "1")):
            lm = LandmarkCreate(id=lid, x=float(lid), y=0.0, z=2.5, floor=floor)
            services.map.create(lm, actor="test")
        site = SiteAdapter(services)
        try:
            assert site.floors() == [("0", "Floor 0"), ("1", "Offices")]
            assert [lm.id for lm in site.landmarks()] == [1, 2, 10]
            site.show_floor("1")
            assert [lm.id for lm in site.landmarks()] == [10]
            assert site.elsewhere() == []  # no robots run without the live site
            with pytest.raises(NotFoundError, match="floor '9'"):
                site.show_floor("9")
            assert [lm.id for lm in site.landmarks()] == [10]  # the choice stays
            site.show_floor(None)
            assert len(site.landmarks()) == 3
        finally:
            site.close()

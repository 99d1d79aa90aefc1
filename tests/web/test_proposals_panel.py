"""The map proposals panel on a real viser server (no browser), a real SQLite map and the
server's map upkeep fed a synthetic drive (tests/survey/test_upkeep.py)."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import numpy as np
import pytest
import viser

from live.facades import Robots
from live.upkeep_service import MapUpkeepService
from pubsub.bus import Bus
from store import MapRepository, RobotStore
from store.db import make_engine, migrate
from store.models import LandmarkCreate
from tests.survey.test_upkeep import ceiling, drive
from web.panels.proposals import NONE, ProposalsPanel
from web.roles import Session

ME = Session("admin", "viewer:key:7")


@pytest.fixture
def upkeep(tmp_path: Path) -> Iterator[MapUpkeepService]:
    engine = make_engine(f"sqlite:///{tmp_path / 'irloc.db'}")
    migrate(engine)
    repo = MapRepository(engine)
    ids, p = ceiling()
    repo.replace_all(
        [LandmarkCreate(id=i, x=x, y=y, z=z, locked=i == 12)
         for i, (x, y, z) in zip(ids, p.tolist(), strict=True)],
        actor="virtual site",
    )  # fmt: skip
    service = MapUpkeepService(repo, Robots(Bus(16), RobotStore(engine), lambda: 0))
    service._on_map(repo.list())  # as `start` does (no pose bus here)
    truth = p.copy()
    truth[ids.index(17)] += (0.03, -0.04, 0.0)
    truth[ids.index(12)] += (-0.04, 0.0, 0.0)
    drive(service, truth, ids, 120)
    yield service
    engine.dispose()


def test_the_panel_lists_accepts_and_rejects_as_the_api_does(
    server: viser.ViserServer, upkeep: MapUpkeepService
) -> None:
    notes: list[str] = []
    panel = ProposalsPanel(server.gui, upkeep, ME, lambda t, b: notes.append(b))
    text = panel.gui_list.content
    assert "**17** moved" in text and "**12** moved **locked**" in text, text
    assert set(panel.gui_choice.options) >= {"17 (moved)", "12 (moved, locked)"}
    assert not panel.gui_accept.disabled
    repo = upkeep.map
    old12 = repo.get(12).x
    # accept all: the unlocked ones only
    done = panel.accept(None)
    assert 17 in done and 12 not in done
    new = np.array([repo.get(17).x, repo.get(17).y])
    assert np.linalg.norm(new - ceiling()[1][7][:2] - (0.03, -0.04)) < 0.005
    audit = repo.audit(5)
    assert audit[0].actor == "viewer:key:7 (map upkeep)"
    assert repo.get(12).x == old12
    # the locked one: rejected by name, its evidence dropped, the map unchanged
    panel.refresh()
    assert panel.gui_choice.options[0] == "12 (moved, locked)", panel.gui_choice.options
    panel.gui_choice.value = "12 (moved, locked)"  # type: ignore[misc]
    assert panel.reject(panel.chosen()) == [12]
    assert repo.get(12).x == old12 and "rejected: 12" in notes[-1]
    assert not any(o.startswith("12 ") for o in panel.gui_choice.options)
    for option in panel.gui_choice.options:  # the rest (refined since): reject them all
        if option != NONE:
            panel.reject(int(option.split()[0]))
    panel.refresh()
    assert panel.gui_choice.options == (NONE,) and panel.gui_accept.disabled
    # nothing chosen: refused, naming why
    assert panel.reject(None) == [] and "name at least one" in notes[-1]

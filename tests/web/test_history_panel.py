"""The undo / redo panel on a real viser server (no browser) and a real SQLite map."""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest
import viser

from store.db import make_engine, migrate
from store.landmarks import MapRepository
from store.models import LandmarkCreate, LandmarkUpdate
from web.panels.history import HistoryPanel, parse_map_file
from web.roles import Session

ME = Session("admin", "viewer:key:7")


@pytest.fixture
def repo(tmp_path: Path) -> Iterator[MapRepository]:
    engine = make_engine(f"sqlite:///{tmp_path / 'irloc.db'}")
    migrate(engine)
    repo = MapRepository(engine)
    repo.replace_all(
        [LandmarkCreate(id=i, x=float(i), y=0.0, z=2.5) for i in (1, 2, 3)], actor="virtual site"
    )
    yield repo
    engine.dispose()


def _panel(server: viser.ViserServer, repo: MapRepository) -> tuple[HistoryPanel, list[str]]:
    notes: list[str] = []
    return HistoryPanel(server.gui, repo, ME, lambda t, b: notes.append(b)), notes


def test_buttons_name_the_next_step_of_this_user_only(
    server: viser.ViserServer, repo: MapRepository
) -> None:
    panel, _ = _panel(server, repo)
    assert panel.gui_undo.label == "Nothing to undo" and panel.gui_undo.disabled
    repo.update(2, LandmarkUpdate(x=2.2), actor="key:7")  # the same key through the API
    repo.update(3, LandmarkUpdate(x=3.3), actor="key:8")  # someone else
    panel.refresh()
    assert panel.gui_undo.label == "Undo move of landmark 2" and not panel.gui_undo.disabled
    panel.request("undo")
    assert repo.get(2).x == 2.0 and repo.get(3).x == 3.3
    assert panel.gui_undo.label == "Nothing to undo" and panel.gui_undo.disabled
    assert panel.gui_redo.label == "Redo move of landmark 2"
    panel.request("undo")  # nothing of mine: the start-up import is nobody's
    assert len(repo.list()) == 3 and "nothing of yours" in panel.gui_status.content


def test_a_whole_map_step_waits_for_the_dialog(
    server: viser.ViserServer, repo: MapRepository
) -> None:
    panel, _ = _panel(server, repo)
    panel.request_import("two.json", b'{"landmarks": [{"id": 9, "x": 0, "y": 1, "z": 2.5}]}')
    assert panel.modal is not None and [lm.id for lm in repo.list()] == [1, 2, 3]
    panel.confirm_dialog()
    assert [lm.id for lm in repo.list()] == [9]
    panel.refresh()
    assert panel.gui_undo.label == "Undo map import (3 -> 1 landmark)"
    panel.request("undo")
    assert panel.modal is not None and [lm.id for lm in repo.list()] == [9]  # only asked
    panel.cancel_dialog()
    assert [lm.id for lm in repo.list()] == [9] and "nothing changed" in panel.gui_status.content
    panel.request("undo")
    panel.confirm_dialog()
    assert [lm.id for lm in repo.list()] == [1, 2, 3]
    panel.request_clear()
    panel.confirm_dialog()
    assert repo.list() == [] and panel.gui_undo.label == "Undo map clear (3 landmarks removed)"


def test_a_bad_map_file_is_refused_naming_it(
    server: viser.ViserServer, repo: MapRepository
) -> None:
    panel, notes = _panel(server, repo)
    panel.request_import("site.json", b"{not json")
    assert panel.modal is None and "site.json: not JSON" in notes[0]
    with pytest.raises(ValueError, match=r"map\.csv: header"):
        parse_map_file("map.csv", b"a,b\n1,2\n")
    assert len(repo.list()) == 3

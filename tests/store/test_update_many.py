"""Several landmark edits in one transaction (the survey's accept): all are written or none,
each stays its own audited, undoable edit."""

from __future__ import annotations

import pytest

from store import MapRepository
from store.db import make_engine, migrate
from store.errors import NotFoundError
from store.models import LandmarkCreate, LandmarkUpdate


@pytest.fixture
def repo(db_url: str) -> MapRepository:
    engine = make_engine(db_url)
    migrate(engine)
    repo = MapRepository(engine)
    for i in (1, 2, 3):
        repo.create(LandmarkCreate(id=i, x=float(i), y=0.0, z=2.5), actor="test")
    return repo


def test_a_failure_midway_writes_none_of_the_edits(repo: MapRepository) -> None:
    edits = [(1, LandmarkUpdate(x=10.0)), (999, LandmarkUpdate(x=0.0)), (3, LandmarkUpdate(x=30.0))]
    with pytest.raises(NotFoundError, match="999"):
        repo.update_many(edits, actor="survey")
    assert [lm.x for lm in repo.list()] == [1.0, 2.0, 3.0]


def test_each_edit_is_audited_and_undone_one_at_a_time(repo: MapRepository) -> None:
    repo.update_many([(1, LandmarkUpdate(x=10.0)), (2, LandmarkUpdate(x=20.0))], actor="survey")
    assert [lm.x for lm in repo.list()] == [10.0, 20.0, 3.0]
    assert [a.landmark_id for a in repo.audit(2)] == [2, 1]
    repo.history.undo("survey")
    assert [lm.x for lm in repo.list()] == [10.0, 2.0, 3.0]

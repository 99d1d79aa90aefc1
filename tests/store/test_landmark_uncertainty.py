"""Each landmark's uncertainty (sigma_m, covariance) and its evidence live with the map:
written by the survey and map upkeep, kept across restarts, voided by a hand edit, shown in
the viewer's label, and used by map upkeep as the landmark's prior."""

from __future__ import annotations

import numpy as np
import pytest

from store.db import make_engine, migrate
from store.landmarks import MapRepository
from store.models import LandmarkCreate, LandmarkUpdate
from survey.upkeep import MapUpkeep
from web.scene import landmark_label
from web.services import LandmarkState

COV = [[1.0e-6, 2.0e-7, 0.0], [2.0e-7, 1.2e-6, 0.0], [0.0, 0.0, 4.0e-6]]


def _repo(db_url: str) -> MapRepository:
    engine = make_engine(db_url)
    migrate(engine)
    return MapRepository(engine)


def test_a_restart_keeps_every_sigma_covariance_and_evidence(db_url: str) -> None:
    repo = _repo(db_url)
    for i in range(5):
        repo.create(LandmarkCreate(id=10 + i, x=float(i), y=1.0, z=2.5), actor="staff")
    sigmas = {10 + i: 0.001 * (i + 1) for i in range(5)}
    for lid, s in sigmas.items():
        repo.update(
            lid,
            LandmarkUpdate(
                x=lid - 10 + 0.01, sigma_m=s, covariance=COV,
                evidence={"source": "survey", "views": 40 + lid, "rms_px": 0.08},
            ),
            actor="staff (survey)",
        )  # fmt: skip
    repo.engine.dispose()
    again = _repo(db_url)  # a restart: a new engine on the same file, migrated again
    for lm in again.list():
        assert lm.sigma_m == pytest.approx(sigmas[lm.id])
        np.testing.assert_allclose(np.array(lm.covariance), np.array(COV))
        assert lm.evidence == {"source": "survey", "views": 40 + lm.id, "rms_px": 0.08}
    exported = {r["id"]: r for r in again.export_json()["landmarks"]}
    assert exported[12]["sigma_m"] == pytest.approx(0.003)  # map.json carries it too


def test_a_hand_edit_of_the_position_voids_the_uncertainty(db_url: str) -> None:
    repo = _repo(db_url)
    repo.create(LandmarkCreate(id=1, x=0.0, y=0.0, z=2.5, sigma_m=0.001, covariance=COV), actor="a")
    assert repo.update(1, LandmarkUpdate(note="checked"), actor="a").sigma_m == 0.001
    lm = repo.update(1, LandmarkUpdate(x=0.2), actor="a")
    assert (lm.sigma_m, lm.covariance, lm.evidence) == (None, None, None)


@pytest.mark.parametrize(
    ("cov", "message"),
    [
        ([[1.0, 0.0], [0.0, 1.0]], "expected 3 x 3"),
        ([[1.0, 0.5, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "not symmetric"),
        ([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]], "non-negative diagonal"),
    ],
)
def test_a_bad_covariance_is_refused_naming_it(cov: list[list[float]], message: str) -> None:
    with pytest.raises(ValueError, match=message):
        LandmarkUpdate(covariance=cov)


def test_the_viewer_label_shows_the_sigma() -> None:
    assert landmark_label(LandmarkState(17, 0.0, 0.0, 2.5, sigma_m=0.0012)) == "17 \u00b11.2 mm"
    assert landmark_label(LandmarkState(18, 0.0, 0.0, 2.5)) == "18"


def test_map_upkeep_takes_the_stored_sigma_as_the_landmarks_prior() -> None:
    up = MapUpkeep()
    up.set_map({1: (0.0, 0.0, 2.5), 2: (1.0, 0.0, 2.5), 3: (2.0, 0.0, 2.5)}, {1: 0.0002, 2: 0.05})
    prior = dict(zip(up._ids, up._sigma.tolist(), strict=True))
    assert prior[1] == pytest.approx(up.config.floor_sigma_m)  # no tighter than the floor
    assert prior[2] == pytest.approx(0.05)  # taped: weighs little
    assert prior[3] == pytest.approx(up.config.map_sigma_m)  # none stored


def test_the_localizers_map_carries_the_stored_sigmas(db_url: str) -> None:
    repo = _repo(db_url)
    repo.create(LandmarkCreate(id=1, x=0.0, y=0.0, z=2.5), actor="a")
    assert repo.landmark_map().sigmas is None  # none stated: the localizer's default
    repo.create(LandmarkCreate(id=2, x=1.0, y=0.0, z=2.5, sigma_m=0.0008), actor="a")
    m = repo.landmark_map()
    assert m.sigma_at(m.index_of(1)) is None
    assert m.sigma_at(m.index_of(2)) == pytest.approx(0.0008)

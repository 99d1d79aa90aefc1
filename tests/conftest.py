"""A short simulated recording of the paper's test bed, shared by the replay, export and
report tests: the identification sweep, 3 s parked, then the first steps of the heading sweep."""

from __future__ import annotations

from pathlib import Path

import pytest

from irloc.simulate_cli import main as simulate


@pytest.fixture(scope="session")
def testbed_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    rec = tmp_path_factory.mktemp("export") / "paper_testbed"
    assert simulate(["paper_testbed", str(rec), "--duration", "3.5", "--quiet"]) == 0
    return rec

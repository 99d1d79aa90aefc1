"""A short simulated recording of the paper's test bed, shared by the replay, export and
report tests: the identification sweep, 3 s parked, then the first steps of the heading sweep."""

from __future__ import annotations

import logging
from collections.abc import Iterator
from pathlib import Path

import pytest

from irloc.simulate_cli import main as simulate

_LOGGERS = ("", "uvicorn", "uvicorn.error", "uvicorn.access")
LONG_FILES = (
    "tests/web/test_browser.py",
    "tests/web/test_browser_operator.py",
    "tests/server/test_survey.py",
    "tests/ros2/test_ros2_live.py",
    "tests/web/test_doubt_live.py",
)
"""The files that take longest (`--durations`), run first: the two workers (`--dist
loadfile`) then share the rest evenly instead of one of them starting a long file last."""


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    def first(item: pytest.Item) -> int:
        path = item.nodeid.split("::", 1)[0]
        return LONG_FILES.index(path) if path in LONG_FILES else len(LONG_FILES)

    items.sort(key=first)  # stable: the order within each file is kept


@pytest.fixture(autouse=True)
def _logging_restored() -> Iterator[None]:
    """The root's and uvicorn's handlers as they were before each test: a test that runs
    `irloc serve` or an agent in-process configures logging onto the stderr capture of that
    test, which is closed after it (later records then fail to print, and pytest's own
    capture handlers, removed by it, would miss every later failure's log)."""
    saved = []
    for name in _LOGGERS:
        lg = logging.getLogger(name)
        saved.append((lg, list(lg.handlers), lg.level, lg.propagate))
    yield
    for lg, handlers, level, propagate in saved:
        for h in list(lg.handlers):
            if h not in handlers:
                lg.removeHandler(h)
        for h in handlers:
            if h not in lg.handlers:
                lg.addHandler(h)
        lg.setLevel(level)
        lg.propagate = propagate


@pytest.fixture(scope="session")
def testbed_recording(tmp_path_factory: pytest.TempPathFactory) -> Path:
    rec = tmp_path_factory.mktemp("export") / "paper_testbed"
    assert simulate(["paper_testbed", str(rec), "--duration", "3.5", "--quiet"]) == 0
    return rec

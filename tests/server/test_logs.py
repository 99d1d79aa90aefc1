"""Log output: one JSON object a line with extra fields, or readable text."""

from __future__ import annotations

import io
import json
import logging
from collections.abc import Iterator

import pytest

from live.settings import Settings
from server.logs import configure_logging
from tests.server.conftest import Api


@pytest.fixture
def restore_root() -> Iterator[None]:
    root = logging.getLogger()
    handlers, level = list(root.handlers), root.level
    yield
    for h in list(root.handlers):
        root.removeHandler(h)
    for h in handlers:
        root.addHandler(h)
    root.setLevel(level)


def test_json_lines_carry_level_logger_message_and_extras(restore_root: None) -> None:
    out = io.StringIO()
    configure_logging("info", "json", stream=out)
    log = logging.getLogger("live.test")
    log.debug("not shown")
    log.warning("landmark %d unreachable", 17, extra={"robot": "r1", "landmark": 17})
    try:
        raise KeyError("boom")
    except KeyError:
        log.exception("failed\non two lines")
    logging.getLogger("uvicorn.error").info("Uvicorn running", extra={"color_message": "\x1b[1m"})
    logging.getLogger("alembic.runtime.plugins").info("setup plugin")  # quiet at info
    lines = out.getvalue().splitlines()
    assert len(lines) == 3
    first, second, third = (json.loads(line) for line in lines)
    assert {k: first[k] for k in ("level", "logger", "message", "robot", "landmark")} == {
        "level": "WARNING",
        "logger": "live.test",
        "message": "landmark 17 unreachable",
        "robot": "r1",
        "landmark": 17,
    }
    assert first["time"].endswith("+00:00") and len(first["time"]) == len(
        "2026-01-02T03:04:05.678+00:00"
    )
    assert second["message"] == "failed\non two lines" and "KeyError: 'boom'" in second["exc"]
    assert third["logger"] == "uvicorn.error" and third["message"] == "Uvicorn running"
    assert "color_message" not in third


def test_text_is_the_default_and_readable(restore_root: None) -> None:
    out = io.StringIO()
    configure_logging("info", Settings().log_format, stream=out)
    logging.getLogger("server.x").info("hello %s", "there", extra={"robot": "r2"})
    assert out.getvalue().rstrip().endswith(" INFO server.x: hello there")


def test_unknown_format_is_refused() -> None:
    with pytest.raises(ValueError, match="log_format"):
        Settings(log_format="yaml")  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="expected 'text' or 'json', got 'xml'"):
        configure_logging("info", "xml")  # type: ignore[arg-type]


def test_site_events_are_logged_with_structured_fields(api: Api, restore_root: None) -> None:
    out = io.StringIO()
    configure_logging("info", "json", stream=out)
    api.services.events.emit("robot_lost", "robot r1 is lost", robot="r1")
    api.services.events.emit("landmark_reachable", "landmark 7 answers again", landmark_id=7)
    got = [json.loads(line) for line in out.getvalue().splitlines()]
    events = [g for g in got if g["logger"] == "live.events"]
    assert [(e["level"], e["event"], e.get("robot"), e.get("landmark")) for e in events] == [
        ("WARNING", "robot_lost", "r1", None),
        ("INFO", "landmark_reachable", None, 7),
    ]


KEY = "irloc_Zq3xW9vT1sR7pL0mN5kJ8hG2fD4aS6yU0iO9eC1bV3n"
ACCESS_PATHS = [
    f"/viewer/?token={KEY}",
    f"/api/v1/poses/ws?robot=r1&token={KEY}",
    f"/api/v1/events/stream?token={KEY}&limit=3",
    f"/api/v1/robots/r1/ws?key={KEY}",
]


@pytest.mark.parametrize("fmt", ["text", "json"])
def test_no_key_reaches_a_log_line(restore_root: None, fmt: str) -> None:
    out = io.StringIO()
    configure_logging("info", fmt, stream=out)  # type: ignore[arg-type]
    access = logging.getLogger("uvicorn.access")
    for path in ACCESS_PATHS:  # uvicorn's own access-line format and arguments
        access.info('%s - "%s %s HTTP/%s" %d', "127.0.0.1:5000", "GET", path, "1.1", 200)
    error = logging.getLogger("uvicorn.error")
    error.info("%s - %s", "127.0.0.1:5000", f'"WebSocket /api/v1/poses/ws?token={KEY}" [accepted]')
    logging.getLogger("server.x").warning("header", extra={"authorization": f"Bearer {KEY}"})
    logging.getLogger("server.x").warning("Authorization: Bearer %s", KEY)
    try:
        raise ValueError(f"bad key {KEY}")
    except ValueError:
        logging.getLogger("server.x").exception("failed")
    text = out.getvalue()
    assert len(text.splitlines()) >= 8
    assert KEY not in text and KEY[:20] not in text
    assert text.count("token=[redacted]") == 4 and "key=[redacted]" in text
    assert "/api/v1/poses/ws?robot=r1&token=[redacted]" in text
    assert "&limit=3" in text  # the rest of the query is kept
    assert "Bearer [redacted]" in text

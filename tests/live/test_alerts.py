"""The alert rules (`live.alerts.AlertBook`) and what the watch reads of a site
(`live.alert_watch.AlertWatch`), on explicit clocks."""

from __future__ import annotations

import itertools
from datetime import UTC, datetime

import numpy as np

from live.alert_watch import AlertWatch
from live.alerts import AlertBook, AlertConfig, Condition
from localizer.events import FrameObserved, OdometryMeasured
from rf_gateway.gateway import Gateway
from tests.live.still_robot import still_runner

WALL = datetime(2026, 12, 7, 20, 0, tzinfo=UTC)
LOST = Condition("robot_lost", "r1", "robot r1 is lost", robot="r1")
CFG = AlertConfig(raise_after_s=3.0, clear_after_s=10.0, min_interval_s=60.0)


def run(book: AlertBook, timeline: list[tuple[float, bool]]) -> list[tuple[float, str]]:
    """Feed `LOST` holding or not at each time; (time, state) of every notification."""
    out: list[tuple[float, str]] = []
    for t, holds in timeline:
        for note in book.update(t, WALL, [LOST] if holds else []):
            out.append((t, note.state))
    return out


def every(t0: float, t1: float, holds: bool, step: float = 0.5) -> list[tuple[float, bool]]:
    return [(t, holds) for t in np.arange(t0, t1, step)]


def test_raised_once_after_holding_then_resolved_after_clearing() -> None:
    book = AlertBook(CFG)
    notes = run(book, every(0, 20, True) + every(20, 40, False))
    assert notes == [(3.0, "raised"), (29.5, "resolved")]
    assert book.active() == []


def test_a_blink_shorter_than_the_hold_raises_nothing() -> None:
    book = AlertBook(CFG)
    timeline = every(0, 2, True) + every(2, 3, False) + every(3, 5.5, True) + every(5.5, 9, False)
    assert run(book, timeline) == []


def test_a_gap_shorter_than_the_clear_time_keeps_the_alert_active() -> None:
    book = AlertBook(CFG)
    notes = run(book, every(0, 5, True) + every(5, 12, False) + every(12, 20, True))
    assert notes == [(3.0, "raised")]
    assert [a.key for a in book.active()] == ["robot_lost:r1"]


def test_a_flapping_condition_raises_at_most_once_per_interval() -> None:
    """Lost 4 s, found 11 s, over and over for 10 minutes: without the minimum interval
    this is 40 raises; with it, one a minute at most."""
    book = AlertBook(CFG)
    timeline: list[tuple[float, bool]] = []
    for k in range(40):
        t = 15.0 * k
        timeline += every(t, t + 4, True) + every(t + 4, t + 15, False)
    notes = run(book, timeline)
    raised = [t for t, s in notes if s == "raised"]
    assert 8 <= len(raised) <= 11, notes
    assert all(b - a >= 60.0 for a, b in itertools.pairwise(raised))
    assert [s for _, s in notes] == ["raised", "resolved"] * len(raised)


def test_unsure_conditions_neither_progress_nor_resolve() -> None:
    book = AlertBook(CFG)
    dead = Condition("landmark_unreachable", "7", "landmark 7 does not answer", landmark_id=7)
    assert book.update(0.0, WALL, [dead]) == []
    assert [n.state for n in book.update(3.0, WALL, [dead])] == ["raised"]
    unsure = {("landmark_unreachable", None)}
    for t in np.arange(3.5, 60, 0.5):  # the radio is down: nothing is known of landmark 7
        assert book.update(float(t), WALL, [], unsure) == []
    assert [n.state for n in book.update(65.0, WALL, [])] == []  # sure again: the clock runs
    assert [n.state for n in book.update(75.5, WALL, [])] == ["resolved"]


def test_details_follow_without_notifying_and_the_payload_names_everything() -> None:
    book = AlertBook(CFG)
    low = Condition("landmark_low_battery", "3", "landmark 3 battery low: 2390 mV", landmark_id=3)
    book.update(0.0, WALL, [low])
    (note,) = book.update(3.0, WALL, [low])
    lower = Condition("landmark_low_battery", "3", "landmark 3 battery low: 2300 mV", landmark_id=3)
    assert book.update(4.0, WALL, [lower]) == []
    assert book.active()[0].condition.message.endswith("2300 mV")
    body = note.to_dict("plant-a")
    assert body["key"] == "landmark_low_battery:3" and body["state"] == "raised"
    assert body["severity"] == "warning" and body["landmark_id"] == 3 and body["active"]
    assert body["text"] == "[irloc plant-a] RAISED warning: landmark 3 battery low: 2390 mV"
    assert body["raised_at"] == WALL.isoformat() and body["resolved_at"] is None


class _NoRadio:
    gateway: Gateway | None = None


def test_the_watch_sees_lost_robots_silent_cameras_and_wheels() -> None:
    now = [100.0]
    frames, wheels = still_runner("frames"), still_runner("wheels")
    lost = still_runner("lost", "lost")
    watch = AlertWatch(lambda: [frames, wheels, lost], _NoRadio(), stale_s=5.0,
                       clock=lambda: now[0])  # fmt: skip
    holding, _ = watch.conditions()
    assert [c.key for c in holding] == ["robot_lost:lost"]
    image = np.zeros((480, 640), np.uint8)
    for t in range(1, 9):  # `frames` gets frames; `wheels` odometry only, then nothing
        now[0] = 100.0 + t
        frames.handle(FrameObserved(t * 10**9, image))
        if t < 3:
            wheels.handle(OdometryMeasured(t * 10**9, 0.1, 0.1))
    keys = sorted(c.key for c in watch.conditions()[0])
    assert keys == [
        "camera_stale:lost",  # never a frame, 8 s since the watch first saw it
        "camera_stale:wheels",
        "odometry_stale:wheels",  # last sample 6 s ago
        "robot_lost:lost",
    ]
    assert "frames" not in " ".join(keys)

"""One failing disk or database never stops the site: recordings and events are written from
their own threads (a failure stops only what failed, with an event), a dead site thread is
started again, and the frame path never waits on storage."""

from __future__ import annotations

import errno
import logging
import threading
import time
from pathlib import Path
from typing import Any, cast

import numpy as np
import pytest
from sqlalchemy.exc import OperationalError

from live.event_writer import EventWriter, PendingEvent
from live.events import EventHub, EventKind
from live.recording_queue import QueuedRecording, RecordingLimits
from live.supervisor import SiteSupervisor
from localizer.robot import RobotGeometry
from recording.writer import RecordingWriter
from sim.cameras import wide_angle_camera

FRAME = np.zeros((8, 8), np.uint8)


def wait_until(cond: Any, timeout_s: float = 5.0) -> bool:
    deadline = time.monotonic() + timeout_s
    while time.monotonic() < deadline:
        if cond():
            return True
        time.sleep(0.01)
    return False


class FailingWriter:
    """A RecordingWriter stand-in whose frames fail with `exc` (or block on `gate`)."""

    def __init__(self, root: Path, exc: BaseException | None = None) -> None:
        self.root = root
        self.exc = exc
        self.gate = threading.Event()
        self.gate.set()
        self.frames = 0
        self.closed = False

    def add_frame(self, t_ns: int, image: Any) -> None:
        self.gate.wait()
        if self.exc is not None:
            raise self.exc
        self.frames += 1

    def add_odometry(self, *a: object) -> None: ...
    def add_leds(self, *a: object) -> None: ...
    def add_pose(self, *a: object) -> None: ...

    def close(self) -> None:
        self.closed = True


def queued(writer: Any, limits: RecordingLimits | None = None) -> tuple[QueuedRecording, list[str]]:
    reasons: list[str] = []
    lim = limits or RecordingLimits(min_free_bytes=0)
    return QueuedRecording(writer, lim, reasons.append, name="r1"), reasons


def test_a_full_disk_stops_the_recording_only_and_says_why(tmp_path: Path) -> None:
    writer = FailingWriter(tmp_path, OSError(errno.ENOSPC, "No space left on device"))
    rec, reasons = queued(writer)
    for t in range(1, 50):
        rec.add_frame(t, FRAME)  # never raises on the feeding thread
    assert wait_until(lambda: reasons)
    assert reasons == ["the disk is full"] and rec.stopped == "the disk is full"
    assert writer.closed
    rec.add_frame(99, FRAME)  # after the stop: ignored, not counted as dropped
    assert rec.close() == tmp_path


def test_a_slow_disk_never_blocks_the_frame_path_frames_are_dropped_and_counted(
    tmp_path: Path,
) -> None:
    writer = FailingWriter(tmp_path)
    writer.gate.clear()  # the disk hangs
    rec, _ = queued(writer, RecordingLimits(min_free_bytes=0, queue_items=8))
    t0 = time.monotonic()
    for t in range(1, 200):
        rec.add_frame(t, FRAME)
    assert time.monotonic() - t0 < 0.5
    assert rec.frames_dropped >= 190
    writer.gate.set()
    rec.close()
    assert writer.frames == 199 - rec.frames_dropped


def test_late_odometry_is_dropped_and_the_recording_goes_on(tmp_path: Path) -> None:
    camera = wide_angle_camera("fisheye")
    writer = RecordingWriter(tmp_path / "rec", camera, RobotGeometry(0.4, 1.0), [])
    rec, reasons = queued(writer)
    rec.add_odometry(2_000, 0.1, 0.1)
    rec.add_odometry(1_000, 0.1, 0.1)  # late: another clock
    rec.add_frame(3_000, FRAME)
    rec.add_odometry(4_000, 0.2, 0.2)
    root = rec.close()
    assert not reasons and rec.late_dropped == 1
    assert (root / "cam0" / "data" / "3000.png").exists()
    assert (root / "odom0" / "data.csv").read_text().count("\n") == 3  # header + 2


def test_a_recording_stops_at_its_duration_limit(tmp_path: Path) -> None:
    rec, reasons = queued(FailingWriter(tmp_path), RecordingLimits(max_s=0.0, min_free_bytes=0))
    time.sleep(0.01)
    rec.add_frame(1, FRAME)
    assert wait_until(lambda: reasons)
    assert "duration limit" in reasons[0]


def test_a_recording_stops_when_the_disk_runs_low(tmp_path: Path) -> None:
    limits = RecordingLimits(min_free_bytes=1 << 62)  # more than any disk has
    rec, reasons = queued(FailingWriter(tmp_path), limits)
    rec.add_frame(1, FRAME)
    assert wait_until(lambda: reasons)
    assert "nearly full" in reasons[0]


class FlakyLog:
    """An EventLog whose database fails while `down` is set (or hangs while `hang`)."""

    def __init__(self) -> None:
        self.down = threading.Event()
        self.hang = threading.Event()
        self.stored: list[str] = []

    def add_event(self, kind: str, message: str, **kw: Any) -> Any:
        while self.hang.is_set():
            time.sleep(0.01)
        if self.down.is_set():
            raise OperationalError("INSERT", {}, Exception("server closed the connection"))
        self.stored.append(kind)
        return type("Rec", (), {"id": len(self.stored)})()


def test_events_are_kept_through_a_database_outage_and_never_block(tmp_path: Path) -> None:
    db = FlakyLog()
    published: list[tuple[str, int]] = []
    writer = EventWriter(db, lambda ev, i: published.append((ev.kind, i)))  # type: ignore[arg-type]
    db.down.set()
    writer.submit(PendingEvent("robot_lost", "r1 lost", "r1", None, {}))
    assert wait_until(lambda: writer.problem is not None)
    assert "database unavailable" in (writer.problem or "")
    assert published == [("robot_lost", 0)]  # shown at once, without an id
    writer.submit(PendingEvent("robot_localized", "r1 back", "r1", None, {}))
    db.down.clear()
    assert wait_until(lambda: db.stored == ["robot_lost", "robot_localized"], 10)
    assert writer.problem is None
    assert ("robot_localized", 0) in published
    writer.close()


def test_emit_returns_at_once_while_the_database_is_locked() -> None:
    db = FlakyLog()
    hub = EventHub(db)  # type: ignore[arg-type]
    db.hang.set()
    t0 = time.monotonic()
    for _ in range(20):
        hub.emit("robot_lost", "r1 is lost", robot="r1")
    assert time.monotonic() - t0 < 0.2
    db.hang.clear()
    assert hub.flush(5.0) and len(db.stored) == 20
    hub.close()


def test_an_unlisted_event_kind_is_logged_and_the_site_carries_on(
    caplog: pytest.LogCaptureFixture,
) -> None:
    """mypy refuses an unlisted kind at the call; one slipping past it (untyped code) must
    not raise on a site thread: it is logged with its message, and not stored (the API's
    enumerated `kind` could not list it)."""
    db = FlakyLog()
    hub = EventHub(db)  # type: ignore[arg-type]
    with caplog.at_level(logging.ERROR, logger="live.events"):
        hub.emit(cast(EventKind, "robot_teleported"), "r1 jumped 40 m", robot="r1")
    hub.emit("robot_lost", "r1 is lost", robot="r1")
    assert hub.flush(5.0) and db.stored == ["robot_lost"]
    assert any(
        "robot_teleported" in r.getMessage() and "r1 jumped 40 m" in r.getMessage()
        for r in caplog.records
    )
    hub.close()


class DyingSource:
    def __init__(self) -> None:
        self.alive = False
        self.revived = 0

    def dead_threads(self) -> list[str]:
        return [] if self.alive else ["site-localizers"]

    def revive(self) -> list[str]:
        self.alive = True
        self.revived += 1
        return ["site-localizers"]


class Runner:
    def __init__(self, name: str) -> None:
        self.name, self.source, self.frames, self.poses = name, "sim", 0, 0


def test_the_supervisor_restarts_a_dead_thread_and_reports_a_stalled_robot() -> None:
    db = FlakyLog()
    hub = EventHub(db)  # type: ignore[arg-type]
    source, r1 = DyingSource(), Runner("r1")
    now = [0.0]
    sup = SiteSupervisor(lambda: [source], lambda: [r1], hub, stall_s=5.0, clock=lambda: now[0])  # type: ignore[arg-type, list-item]
    sup.check()
    assert source.revived == 1 and not sup.problems()
    assert hub.flush() and db.stored == ["site_thread_restarted"]
    now[0] = 3.0
    r1.frames = 10
    sup.check()
    now[0] = 9.0
    sup.check()
    assert sup.problems() == ["robot r1: no frame localized for 6 s"]
    hub.close()


def test_a_steady_flow_of_events_does_not_hold_back_the_retries() -> None:
    db = FlakyLog()
    writer = EventWriter(db, lambda ev, i: None)  # type: ignore[arg-type]
    db.down.set()
    t_end = time.monotonic() + 1.5
    n = 0
    while time.monotonic() < t_end:
        writer.submit(PendingEvent("map_changed", f"edit {n}", None, None, {}))
        n += 1
        if n == 10:
            db.down.clear()  # the database is back while events keep coming
        time.sleep(0.05)
    assert wait_until(lambda: len(db.stored) == n, 5.0), (len(db.stored), n)
    assert writer.problem is None
    writer.close()

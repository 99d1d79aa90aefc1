"""`EventBuffer`: events handed out in time order, and how far every stream has delivered
(`complete_until`): a stream that fell behind holds the others back, one silent for longer
than the wait does not, and nothing is complete before the first event."""

from __future__ import annotations

import numpy as np

from localizer.events import FrameObserved, OdometryMeasured
from sensors.event_buffer import EventBuffer

MS = 1_000_000
WAIT = 1_000 * MS


def frame(t_ns: int) -> FrameObserved:
    return FrameObserved(t_ns, np.zeros((2, 2), np.uint8))


def test_events_come_out_in_time_order_up_to_the_time_asked() -> None:
    buffer = EventBuffer()
    for e in (OdometryMeasured(30, 0, 0), frame(10), OdometryMeasured(20, 0, 0)):
        buffer("r1", e)
    assert [e.t_ns for e in buffer.take_due(20)] == [10, 20]
    assert [e.t_ns for e in buffer.take_due(100)] == [30]
    assert buffer.received == {"r1": 3}


def test_nothing_is_complete_before_the_first_event() -> None:
    assert EventBuffer().complete_until(5_000 * MS, WAIT) == -1


def test_the_stream_furthest_behind_sets_how_far_all_are_complete() -> None:
    buffer = EventBuffer()
    buffer("r1", frame(1_000 * MS))
    buffer("r1", OdometryMeasured(1_300 * MS, 0, 0))
    assert buffer.complete_until(1_200 * MS, WAIT) == 1_000 * MS  # the camera is behind
    assert buffer.complete_until(900 * MS, WAIT) == 900 * MS  # both past it
    buffer("r1", frame(1_400 * MS))
    assert buffer.complete_until(1_500 * MS, WAIT) == 1_300 * MS  # now the wheels are


def test_a_stream_silent_for_longer_than_the_wait_is_taken_for_stopped() -> None:
    buffer = EventBuffer()
    buffer("r1", OdometryMeasured(1_000 * MS, 0, 0))  # the wheels went quiet
    buffer("r1", frame(2_950 * MS))
    assert buffer.complete_until(2_900 * MS, WAIT) == 2_900 * MS
    assert buffer.complete_until(1_900 * MS, WAIT) == 1_000 * MS  # within the wait: held


def test_each_robot_and_kind_is_its_own_stream() -> None:
    buffer = EventBuffer()
    buffer("r1", frame(1_000 * MS))
    buffer("r2", frame(500 * MS))
    buffer("r1", OdometryMeasured(1_000 * MS, 0, 0))
    assert buffer.complete_until(800 * MS, WAIT) == 500 * MS  # r2's camera

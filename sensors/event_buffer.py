"""`EventBuffer`: a `SensorSink` that keeps what push sources deliver until a pull loop asks.

The on-robot agent steps its localizer on its own tick (`agent.core.AgentCore.tick`): the
camera and wheel threads push events into the buffer, and each tick takes those due so far,
in time order.

A stream (one robot's frames, or its wheel samples) that falls behind, because its thread or
the transport stalled, holds the others back rather than being overtaken:
`complete_until(t)` is how far every live stream has delivered, so what a stall delays is
still fed in time order once it arrives, not dropped as late. A stream further behind than
`max_wait_ns` is taken for stopped (a camera unplugged, wheels that went quiet) and no
longer waited for; nothing is complete before the first event arrives.
"""

from __future__ import annotations

import threading

from localizer.events import OdometryMeasured
from sensors.sources import SensorEvent


class EventBuffer:
    """Collects one robot's sensor events from any thread; `take_due(t_ns)` hands them out.

    Attributes:
        received: events received so far, by robot name (a source names the robot it feeds).
    """

    def __init__(self) -> None:
        self._events: list[SensorEvent] = []
        self._lock = threading.Lock()
        self.received: dict[str, int] = {}
        self._latest: dict[tuple[str, str], int] = {}

    def __call__(self, robot: str, event: SensorEvent) -> None:
        stream = (robot, "wheels" if isinstance(event, OdometryMeasured) else "camera")
        with self._lock:
            self._events.append(event)
            self.received[robot] = self.received.get(robot, 0) + 1
            self._latest[stream] = max(self._latest.get(stream, event.t_ns), event.t_ns)

    def complete_until(self, t_ns: int, max_wait_ns: int) -> int:
        """`t_ns`, or the stamp of the latest event of a stream that has not reached it yet
        but is less than `max_wait_ns` behind (the earliest such): up to there every live
        stream has delivered. Before the first event, nothing is complete (-1): a source
        starting up is not overtaken by the clock either."""
        with self._lock:
            if not self._latest:
                return -1
            behind = [t for t in self._latest.values() if t_ns - max_wait_ns < t < t_ns]
        return min(behind, default=t_ns)

    def take_due(self, t_ns: int) -> list[SensorEvent]:
        """The events stamped at or before `t_ns`, in time order (removed from the buffer)."""
        with self._lock:
            self._events.sort(key=lambda e: e.t_ns)
            n = next((i for i, e in enumerate(self._events) if e.t_ns > t_ns), len(self._events))
            due, self._events = self._events[:n], self._events[n:]
        return due

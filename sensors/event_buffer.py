"""`EventBuffer`: a `SensorSink` that keeps what push sources deliver until a pull loop asks.

The on-robot agent steps its localizer on its own tick (`agent.core.AgentCore.tick`): the
camera and wheel threads push events into the buffer, and each tick takes those due so far,
in time order.
"""

from __future__ import annotations

import threading

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

    def __call__(self, robot: str, event: SensorEvent) -> None:
        with self._lock:
            self._events.append(event)
            self.received[robot] = self.received.get(robot, 0) + 1

    def take_due(self, t_ns: int) -> list[SensorEvent]:
        """The events stamped at or before `t_ns`, in time order (removed from the buffer)."""
        with self._lock:
            self._events.sort(key=lambda e: e.t_ns)
            n = next((i for i, e in enumerate(self._events) if e.t_ns > t_ns), len(self._events))
            due, self._events = self._events[:n], self._events[n:]
        return due

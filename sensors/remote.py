"""A remote robot's sensor stream (`WS /robots/{name}/ws`, server/routes/remote.py)."""

from __future__ import annotations

import asyncio

from sensors.sources import SensorEvent, SensorSink


class RemoteSource:
    """A remote robot's stream (`WS /robots/{name}/ws`, server/routes/remote.py) as a
    `FrameSource`: the route `await push(event)`es what the robot sent; each event is fed
    on a worker thread (the localizer must not run on the server's loop).

    Args:
        robot: the robot's name.
    """

    def __init__(self, robot: str) -> None:
        self.robot = robot
        self.robots = (robot,)
        self._sink: SensorSink | None = None

    def start(self, sink: SensorSink) -> None:
        self._sink = sink

    def stop(self) -> None:
        self._sink = None

    async def push(self, event: SensorEvent) -> None:
        """Feed one event and return once the localizer handled it (dropped when stopped)."""
        sink = self._sink
        if sink is not None:
            await asyncio.to_thread(sink, self.robot, event)

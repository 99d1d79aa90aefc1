"""Where robots' sensor events come from: the `FrameSource` protocol every source implements
(the virtual site's `sensors.sim_source.SimSource`, a UVC camera or video file
`sensors.camera.CameraSource`, wheel speeds on a serial line `sensors.serial_wheels`, a remote
robot's WebSocket `sensors.remote.RemoteSource`), used by the server and the on-robot agent
alike (the agent collects the events with `sensors.event_buffer.EventBuffer`).

Every source feeds the localizers the same way: `start(sink)`, then it calls
`sink(robot, event)` with `FrameObserved`, `SpotsObserved` or `OdometryMeasured` events on
the site clock, from its own thread (the sink, `live.facades.Robots.deliver`, hands each to
the robot's `RobotRunner`, which is thread-safe); `stop()` ends it. docs/architecture.md
("The live path") draws it.
"""

from __future__ import annotations

from collections.abc import Sequence
from typing import Protocol

from localizer.events import FrameObserved, OdometryMeasured, SpotsObserved

SensorEvent = FrameObserved | SpotsObserved | OdometryMeasured
"""What a source delivers: a frame (or its detected spots) or a wheel-speed sample."""


class SensorSink(Protocol):
    """Takes one robot's sensor event (thread-safe; returns when the localizer is done)."""

    def __call__(self, robot: str, event: SensorEvent) -> None: ...


class FrameSource(Protocol):
    """A source of sensor events for one or more robots.

    Attributes:
        robots: the names of the robots it feeds.
    """

    @property
    def robots(self) -> Sequence[str]: ...

    def start(self, sink: SensorSink) -> None:
        """Begin delivering events to `sink` (returns at once)."""
        ...

    def stop(self) -> None:
        """Stop delivering (blocks until its thread ended; idempotent)."""
        ...

"""Where robots' sensor events come from: the `FrameSource` protocol and the sources of the
server (a camera on the server, a remote robot over the WebSocket; the virtual site's is
`sensors.sim_source.SimSource`, serial wheel speeds `sensors.serial_wheels`).

Every source feeds the localizers the same way: `start(sink)`, then it calls
`sink(robot, event)` with `FrameObserved`, `SpotsObserved` or `OdometryMeasured` events on
the site clock, from its own thread (the sink, `live.facades.Robots.deliver`, hands each to
the robot's `RobotRunner`, which is thread-safe); `stop()` ends it. docs/architecture.md
("The live path") draws it; the on-robot agent implements the same protocol.
"""

from __future__ import annotations

import asyncio
import logging
import threading
from collections.abc import Callable, Sequence
from typing import Protocol

import cv2
import numpy as np

from localizer.events import FrameObserved, OdometryMeasured, SpotsObserved

log = logging.getLogger(__name__)

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


def to_gray(image: np.ndarray) -> np.ndarray:
    """8-bit grayscale, shape (H, W), from a BGR/gray/16-bit frame."""
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.dtype != np.uint8:
        image = cv2.convertScaleAbs(image, alpha=255.0 / max(1.0, float(image.max())))
    return np.ascontiguousarray(image)


class CameraSource:
    """A robot's frames from `cv2.VideoCapture(device)` on a thread (a `FrameSource`).

    Args:
        robot: the robot's name.
        device: a camera index ("0") or a video file / stream URL.
        clock_ns: the site clock stamping frames.
        rate_hz: pacing for files (cameras pace themselves).
    """

    def __init__(
        self, robot: str, device: str, clock_ns: Callable[[], int], rate_hz: float = 30.0
    ) -> None:
        self.robot = robot
        self.robots = (robot,)
        self.device = device
        self.clock_ns = clock_ns
        self.period_s = 1.0 / rate_hz
        self._stop = threading.Event()
        self._sink: SensorSink | None = None
        self._thread = threading.Thread(target=self._run, name=f"camera-{robot}", daemon=True)

    def start(self, sink: SensorSink) -> None:
        self._sink = sink
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        if self._thread.is_alive():
            self._thread.join(timeout=5)

    def _run(self) -> None:
        assert self._sink is not None  # started
        target: int | str = int(self.device) if self.device.isdigit() else self.device
        cap = cv2.VideoCapture(target)
        extra = {"robot": self.robot}
        if not cap.isOpened():
            log.error("robot %s: cannot open camera %r", self.robot, self.device, extra=extra)
            return
        is_file = isinstance(target, str)
        try:
            while not self._stop.is_set():
                ok, frame = cap.read()
                if not ok:
                    log.info("robot %s: camera %r ended", self.robot, self.device, extra=extra)
                    return
                self._sink(self.robot, FrameObserved(self.clock_ns(), to_gray(frame)))
                if is_file:
                    self._stop.wait(self.period_s)
        finally:
            cap.release()


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

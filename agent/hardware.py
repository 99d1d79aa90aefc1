"""A real robot's sensors for the agent: its upward camera (`sensors.camera.CameraSource`: a
device index, a video file or an image sequence such as `frames/%04d.png`) and its wheel
speeds (`$IRODO` lines on a serial port, `sensors.serial_wheels.SerialWheelSource`), the same
drivers the server uses, each on its own thread and stamped on receipt with the agent's
monotonic clock (a line's own `t_ns` is ignored: it is on the robot controller's clock). The
agent's tick takes what they delivered from an `EventBuffer`. The LEDs are real:
`apply_leds` has nothing to do.
"""

from __future__ import annotations

import time
from collections.abc import Iterable

from localizer.camera import CameraModel
from localizer.events import Event
from localizer.robot import RobotGeometry
from sensors.camera import CameraSource
from sensors.event_buffer import EventBuffer
from sensors.serial_wheels import SerialWheelSource
from sensors.sources import FrameSource

ROBOT = "self"
"""The name the agent's own sources deliver under (the agent feeds one robot)."""


class HardwareSource:
    """Camera and wheels of the robot the agent runs on (an `agent.core.SensorSource`).

    Args:
        camera: the calibrated camera (its `sensor.yaml`).
        geometry: the robot's wheel base and top speed.
        device: camera index ("0") or video file / image sequence (None: no camera).
        wheels: serial port (device or pyserial URL) of the wheel lines (None: none).
        baud: its baud rate.
        file_rate_hz: pacing of a video file or image sequence (cameras pace themselves).
        retry_s: pause before reopening a missing port or camera, seconds.
    """

    def __init__(
        self,
        camera: CameraModel,
        geometry: RobotGeometry,
        *,
        device: str | None,
        wheels: str | None,
        baud: int = 115200,
        file_rate_hz: float = 30.0,
        retry_s: float = 1.0,
    ) -> None:
        self._camera = camera
        self._geometry = geometry
        self.device = device
        self.wheels = wheels
        self._buffer = EventBuffer()
        clock = time.monotonic_ns
        self.camera_source = (
            None
            if device is None
            else CameraSource(ROBOT, device, clock, rate_hz=file_rate_hz, retry_s=retry_s)
        )
        self.wheel_source = (
            None
            if wheels is None
            else SerialWheelSource(ROBOT, wheels, baud, clock, retry_s=retry_s, line_time=False)
        )
        self._sources: list[FrameSource] = [
            s for s in (self.camera_source, self.wheel_source) if s is not None
        ]

    @property
    def camera(self) -> CameraModel:
        return self._camera

    @property
    def geometry(self) -> RobotGeometry:
        return self._geometry

    @property
    def start_pose(self) -> tuple[float, float, float] | None:
        return None

    @property
    def frames(self) -> int:
        """Frames the camera delivered so far."""
        return 0 if self.camera_source is None else self.camera_source.frames

    @property
    def lines(self) -> int:
        """Good wheel lines so far."""
        return 0 if self.wheel_source is None else self.wheel_source.lines

    @property
    def bad_lines(self) -> int:
        """Wheel lines skipped (checksum, fields, values)."""
        return 0 if self.wheel_source is None else self.wheel_source.bad_lines

    def start(self) -> None:
        for s in self._sources:
            s.start(self._buffer)

    def stop(self) -> None:
        for s in self._sources:
            s.stop()

    def complete_until(self, t_ns: int, max_wait_ns: int) -> int:
        """How far the camera and the wheels both delivered (`EventBuffer.complete_until`)."""
        return self._buffer.complete_until(t_ns, max_wait_ns)

    def step(self, t_ns: int) -> list[Event]:
        """The samples taken up to `t_ns` (the agent's monotonic clock), in time order."""
        return list(self._buffer.take_due(t_ns))

    def apply_leds(self, t_ns: int, lit: Iterable[int] | None) -> None:
        """Real LEDs switch themselves."""

    def true_pose_at(self, t_ns: int) -> tuple[float, float, float] | None:
        return None

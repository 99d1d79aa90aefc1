"""A real robot's sensors for the agent: its upward camera (OpenCV `VideoCapture`: a device
index, a video file or an image sequence such as `frames/%04d.png`) and its wheel speeds
(`$IRODO` lines on a serial port, `fleet.serial_lines`), each read on its own thread and
stamped on receipt with the agent's monotonic clock (a line's own `t_ns` is ignored: it is
on the robot controller's clock). A bad line is counted and skipped with a warning; a
missing or unplugged port is retried every `retry_s`. The LEDs are real: `apply_leds` has
nothing to do.
"""

from __future__ import annotations

import logging
import threading
import time
from collections.abc import Iterable
from typing import Any

import cv2
import numpy as np

from fleet.serial_lines import LineBuffer, parse_wheel_line
from localizer.camera import CameraModel
from localizer.events import Event, FrameObserved, OdometryMeasured
from localizer.robot import RobotGeometry

log = logging.getLogger(__name__)


class HardwareSource:
    """Camera and wheels of the robot the agent runs on (a `agent.core.SensorSource`).

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
        self.baud = baud
        self.file_period_s = 1.0 / file_rate_hz
        self.retry_s = retry_s
        self.frames = 0
        self.lines = 0
        self.bad_lines = 0
        self._events: list[Event] = []
        self._lock = threading.Lock()
        self._stop = threading.Event()
        self._threads = [
            threading.Thread(target=fn, name=name, daemon=True)
            for fn, name, on in ((self._run_camera, "agent-camera", device is not None),
                                 (self._run_wheels, "agent-wheels", wheels is not None))
            if on
        ]  # fmt: skip

    @property
    def camera(self) -> CameraModel:
        return self._camera

    @property
    def geometry(self) -> RobotGeometry:
        return self._geometry

    @property
    def start_pose(self) -> tuple[float, float, float] | None:
        return None

    def start(self) -> None:
        for t in self._threads:
            t.start()

    def stop(self) -> None:
        self._stop.set()
        for t in self._threads:
            t.join(timeout=5)

    def step(self, t_ns: int) -> list[Event]:
        """The samples taken up to `t_ns` (the agent's monotonic clock), in time order."""
        with self._lock:
            self._events.sort(key=lambda e: e.t_ns)
            n = next((i for i, e in enumerate(self._events) if e.t_ns > t_ns), len(self._events))
            due, self._events = self._events[:n], self._events[n:]
        return due

    def apply_leds(self, t_ns: int, lit: Iterable[int] | None) -> None:
        """Real LEDs switch themselves."""

    def true_pose_at(self, t_ns: int) -> tuple[float, float, float] | None:
        return None

    def _put(self, event: Event) -> None:
        with self._lock:
            self._events.append(event)

    # -- camera --------------------------------------------------------------------------------
    def _run_camera(self) -> None:
        assert self.device is not None
        target: int | str = int(self.device) if self.device.isdigit() else self.device
        while not self._stop.is_set():
            cap = cv2.VideoCapture(target)
            if not cap.isOpened():
                log.warning("camera %r cannot be opened; retrying", self.device)
                self._stop.wait(self.retry_s)
                continue
            try:
                while not self._stop.is_set():
                    ok, frame = cap.read()
                    if not ok:
                        log.info("camera %r ended", self.device)
                        return
                    self._put(FrameObserved(time.monotonic_ns(), gray8(frame)))
                    self.frames += 1
                    if isinstance(target, str):
                        self._stop.wait(self.file_period_s)
            finally:
                cap.release()

    # -- wheels --------------------------------------------------------------------------------
    def handle_line(self, raw: bytes) -> None:
        """One received line (without its LF): an odometry sample, or counted and skipped."""
        try:
            _, v_left, v_right = parse_wheel_line(raw.decode("ascii"))
        except (UnicodeDecodeError, ValueError) as exc:
            self.bad_lines += 1
            log.warning("wheel line skipped on %s: %s", self.wheels, exc)
            return
        self._put(OdometryMeasured(time.monotonic_ns(), v_left, v_right))
        self.lines += 1

    def _run_wheels(self) -> None:
        import serial

        while not self._stop.is_set():
            try:
                port: Any = serial.serial_for_url(self.wheels, baudrate=self.baud, timeout=0.2)
            except Exception as exc:  # SerialException, OSError, ValueError
                log.warning("wheel port %s unavailable (%s); retrying", self.wheels, exc)
                self._stop.wait(self.retry_s)
                continue
            try:
                lines = LineBuffer()
                while not self._stop.is_set():
                    for raw in lines.feed(port.read(max(1, port.in_waiting))):
                        self.handle_line(raw)
            except Exception as exc:  # the adapter went away (EIO, unplugged)
                log.warning("wheel port %s lost (%s); reconnecting", self.wheels, exc)
            finally:
                port.close()
            self._stop.wait(self.retry_s)


def gray8(image: np.ndarray) -> np.ndarray:
    """8-bit grayscale (H, W) of a camera frame (BGR, gray, or 16-bit)."""
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.dtype != np.uint8:
        image = cv2.convertScaleAbs(image, alpha=255.0 / max(1.0, float(image.max())))
    return np.ascontiguousarray(image)

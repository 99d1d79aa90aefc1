"""A robot's upward camera through OpenCV: a UVC device, a video file or an image sequence.

`CameraSource` reads `cv2.VideoCapture(device)` on its own thread and delivers each frame as
`FrameObserved` (8-bit gray, `to_gray`) stamped on receipt by the clock it is given (the
server's site clock, or the agent's monotonic clock). A camera that cannot be opened is
retried every `retry_s`; a file or image sequence is paced at `rate_hz` and ends the source
when it ends (a device paces itself).
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

import cv2
import numpy as np

from localizer.events import FrameObserved
from sensors.sources import SensorSink

log = logging.getLogger(__name__)


def to_gray(image: np.ndarray) -> np.ndarray:
    """8-bit grayscale, shape (H, W), from a BGR, gray or 16-bit frame.

    16-bit (or float) frames are scaled so that their brightest pixel maps to 255.
    """
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.dtype != np.uint8:
        image = cv2.convertScaleAbs(image, alpha=255.0 / max(1.0, float(image.max())))
    return np.ascontiguousarray(image)


class CameraSource:
    """A robot's frames from `cv2.VideoCapture(device)` on a thread (a `FrameSource`).

    Args:
        robot: the robot's name.
        device: a camera index ("0"), a video file, or an image sequence (`frames/%04d.png`).
        clock_ns: the clock stamping frames on receipt.
        rate_hz: pacing of a file or image sequence (devices pace themselves).
        retry_s: pause before reopening a camera that cannot be opened, seconds; None: give
            up at the first failure (logged as an error).

    Attributes:
        frames: frames delivered so far.
        opened: whether the camera is open now.
    """

    def __init__(
        self,
        robot: str,
        device: str,
        clock_ns: Callable[[], int],
        *,
        rate_hz: float = 30.0,
        retry_s: float | None = 1.0,
    ) -> None:
        if rate_hz <= 0:
            raise ValueError(f"camera {device!r}: rate_hz must be > 0, got {rate_hz}")
        self.robot = robot
        self.robots = (robot,)
        self.device = device
        self.clock_ns = clock_ns
        self.period_s = 1.0 / rate_hz
        self.retry_s = retry_s
        self.frames = 0
        self.opened = False
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
        target: int | str = int(self.device) if self.device.isdigit() else self.device
        extra = {"robot": self.robot}
        while not self._stop.is_set():
            cap = cv2.VideoCapture(target)
            if not cap.isOpened():
                cap.release()
                if self.retry_s is None:
                    log.error(
                        "robot %s: cannot open camera %r", self.robot, self.device, extra=extra
                    )
                    return
                log.warning(
                    "robot %s: camera %r cannot be opened; retrying every %.1f s",
                    self.robot,
                    self.device,
                    self.retry_s,
                    extra=extra,
                )
                self._stop.wait(self.retry_s)
                continue
            try:
                self.opened = True
                if self._read(cap, paced=isinstance(target, str)):
                    return
            finally:
                self.opened = False
                cap.release()

    def _read(self, cap: cv2.VideoCapture, *, paced: bool) -> bool:
        """Deliver frames until stopped or the stream ends; True when it ended."""
        while not self._stop.is_set():
            ok, frame = cap.read()
            if not ok:
                log.info("robot %s: camera %r ended", self.robot, self.device)
                return True
            sink = self._sink
            if sink is not None:
                sink(self.robot, FrameObserved(self.clock_ns(), to_gray(frame)))
            self.frames += 1
            if paced:
                self._stop.wait(self.period_s)
        return False

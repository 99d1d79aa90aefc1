"""Where a robot's frames come from besides the virtual site: a camera on the server
(OpenCV `VideoCapture`, a device index or a video file)."""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable

import cv2
import numpy as np

from localizer.events import FrameObserved
from server.site.robot import RobotRunner

log = logging.getLogger(__name__)


def to_gray(image: np.ndarray) -> np.ndarray:
    """8-bit grayscale, shape (H, W), from a BGR/gray/16-bit frame."""
    if image.ndim == 3:
        image = cv2.cvtColor(image, cv2.COLOR_BGR2GRAY)
    if image.dtype != np.uint8:
        image = cv2.convertScaleAbs(image, alpha=255.0 / max(1.0, float(image.max())))
    return np.ascontiguousarray(image)


class CameraSource:
    """Feed a robot's localizer from `cv2.VideoCapture(device)` on a thread.

    Args:
        runner: the robot.
        device: a camera index ("0") or a video file / stream URL.
        clock_ns: the site clock stamping frames.
        rate_hz: pacing for files (cameras pace themselves).
    """

    def __init__(
        self, runner: RobotRunner, device: str, clock_ns: Callable[[], int], rate_hz: float = 30.0
    ) -> None:
        self.runner = runner
        self.device = device
        self.clock_ns = clock_ns
        self.period_s = 1.0 / rate_hz
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"camera-{runner.name}", daemon=True)

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)

    def _run(self) -> None:
        target: int | str = int(self.device) if self.device.isdigit() else self.device
        cap = cv2.VideoCapture(target)
        if not cap.isOpened():
            log.error(
                "robot %s: cannot open camera %r",
                self.runner.name,
                self.device,
                extra={"robot": self.runner.name},
            )
            return
        is_file = isinstance(target, str)
        try:
            while not self._stop.is_set():
                ok, frame = cap.read()
                if not ok:
                    log.info(
                        "robot %s: camera %r ended",
                        self.runner.name,
                        self.device,
                        extra={"robot": self.runner.name},
                    )
                    return
                self.runner.handle(FrameObserved(self.clock_ns(), to_gray(frame)))
                if is_file:
                    self._stop.wait(self.period_s)
        finally:
            cap.release()

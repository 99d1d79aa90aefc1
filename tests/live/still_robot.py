"""A live robot whose localizer does nothing but keep the mode a test sets (for what reads
robots: alerts, health)."""

from __future__ import annotations

from typing import Any

import numpy as np

from live.robots import RobotRunner
from localizer.camera import CameraModel
from localizer.events import Mode, OdometryMeasured
from localizer.robot import RobotGeometry


class StillLocalizer:
    def __init__(self, mode: Mode) -> None:
        self.mode: Mode = mode

    def handle(self, event: Any) -> list[Any]:
        return []

    def set_map(self, landmark_map: Any) -> None:
        return None


def still_runner(name: str, mode: Mode = "landmark", source: str = "camera") -> RobotRunner:
    cam = CameraModel(640, 480, 400.0, 400.0, 320.0, 240.0, "radial-tangential", np.zeros(5),
                      np.eye(4))  # fmt: skip
    geometry = RobotGeometry(0.4, 1.0)
    return RobotRunner(name, cam, geometry, StillLocalizer(mode), publish=lambda _: None,
                       request_leds=lambda *_: None, source=source)  # fmt: skip


def set_mode(runner: RobotRunner, mode: Mode, t_ns: int) -> None:
    """Make the runner's localizer report `mode` (seen at the next event it is fed)."""
    loc = runner.localizer
    assert isinstance(loc, StillLocalizer)
    loc.mode = mode
    runner.handle(OdometryMeasured(t_ns, 0.0, 0.0))

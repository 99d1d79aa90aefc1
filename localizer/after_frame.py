"""What a fused frame leaves to learn after its pose is out.

A frame's pose is what the camera loop waits for; some of what the frame teaches is needed
only by later frames: which landmarks were seen where predicted (`LandmarkLiveness`), the
online self-calibration's window and its steps (`OnlineCalibration`), the motion model's
measurement of the fix (`ConstantVelocity.fixed`). That work is queued here with the
frame's values captured, and run by the localizer before it handles anything else: the
next event, usually an odometry or IMU sample between frames. Any later event sees the
same state as if it had been done with the frame.
"""

from __future__ import annotations

from collections.abc import Callable


class AfterFrame:
    """A queue of a frame's learning, run in order by `run`."""

    def __init__(self) -> None:
        self._work: list[Callable[[], None]] = []

    def defer(self, work: Callable[[], None]) -> None:
        """Queue `work` (a closure over the frame's values) for after the frame's pose."""
        self._work.append(work)

    def run(self) -> None:
        """Do the queued work, oldest first."""
        while self._work:
            self._work.pop(0)()

"""The serial pose output (the paper's UART to the robot): one NMEA-style line per pose.

Line format (ASCII, CR LF terminated):

    $IRLOC,<robot>,<t_ns>,<x>,<y>,<theta>,<mode>*<CS>

`x`, `y` in metres (3 decimals), `theta` in radians (4 decimals, REP-103, (-pi, pi]); the
three are empty while there is no pose. `mode` is identifying | landmark | dead_reckoning |
lost. `CS` is the NMEA checksum: the XOR of every byte between `$` and `*`, two uppercase hex
digits (framing in `line_framing`). Example: `$IRLOC,r1,1500000000,1.234,-0.500,0.7854,landmark*5C`.
"""

from __future__ import annotations

import logging
import threading
from typing import IO, Any

from live.poses import PoseUpdate
from pubsub.bus import Subscription
from sensors.line_framing import frame_line, nmea_checksum, unframe_line

__all__ = ["SerialSink", "nmea_checksum", "parse_pose_line", "pose_line"]

log = logging.getLogger(__name__)


def pose_line(upd: PoseUpdate) -> str:
    """The line for one pose, with checksum and CR LF."""
    has = upd.x is not None and upd.y is not None and upd.theta is not None
    xyz = f"{upd.x:.3f},{upd.y:.3f},{upd.theta:.4f}" if has else ",,"
    return frame_line(f"IRLOC,{upd.robot},{upd.t_ns},{xyz},{upd.mode}")


def parse_pose_line(line: str) -> dict[str, Any]:
    """Inverse of `pose_line` (for robots written in Python, and tests).

    Raises:
        ValueError: a malformed line or a wrong checksum, naming what is wrong.
    """
    parts = unframe_line(line, "pose line")
    if len(parts) != 7 or parts[0] != "IRLOC":
        raise ValueError(f"pose line {line!r}: expected 7 fields starting with IRLOC")
    _, robot, t_ns, x, y, theta, mode = parts
    num = [None if v == "" else float(v) for v in (x, y, theta)]
    return {
        "robot": robot,
        "t_ns": int(t_ns),
        "x": num[0],
        "y": num[1],
        "theta": num[2],
        "mode": mode,
    }


class SerialSink:
    """Write every pose of `subscription` to a serial port (or any binary stream) on a
    thread; the bounded subscription drops poses if the line is too slow.

    Args:
        subscription: poses to send (filter it to the robot on the other end).
        stream: an open binary stream (`serial.Serial`, a file).
    """

    def __init__(self, subscription: Subscription[PoseUpdate], stream: IO[bytes]) -> None:
        self.subscription = subscription
        self.stream = stream
        self.lines = 0
        self._thread = threading.Thread(target=self._run, name="serial-sink", daemon=True)

    @classmethod
    def open(cls, subscription: Subscription[PoseUpdate], port: str, baud: int) -> SerialSink:
        """On a serial port (pyserial URL or device path)."""
        import serial

        return cls(subscription, serial.serial_for_url(port, baudrate=baud, timeout=1))

    def start(self) -> None:
        self._thread.start()

    def stop(self) -> None:
        self.subscription.close()
        self._thread.join(timeout=5)
        self.stream.close()

    def _run(self) -> None:
        while not self.subscription.closed:
            upd = self.subscription.get(timeout_s=0.5)
            if upd is None:
                continue
            try:
                self.stream.write(pose_line(upd).encode("ascii"))
                self.stream.flush()
                self.lines += 1
            except (OSError, ValueError) as exc:
                log.error("serial sink stopped: %s", exc)
                return

"""Wheel speeds from a robot over a serial line (for a robot whose camera is on the server).

Line format (ASCII, CR LF terminated, the framing of `line_framing`):

    $IRODO,<t_ns>,<v_left>,<v_right>*<CS>

`v_left`, `v_right`: wheel speeds in m/s (|v| <= 20, forward positive); `t_ns`: the time
of the measurement on the server's site clock, or empty to be stamped on receipt (a robot
that does not share the site clock leaves it empty). `CS`: XOR of the bytes between `$` and
`*`, two hex digits. Example: `$IRODO,,0.200,0.215*77`.

`SerialWheelSource` (a `sensors.sources.FrameSource` of odometry only) reads such
lines on a thread and feeds `OdometryMeasured` to the robot's localizer. A bad line
(checksum, fields, values, too long) is counted and skipped with a warning; when the port
cannot be opened or disappears, it retries every `retry_s`.
"""

from __future__ import annotations

import logging
import threading
from collections.abc import Callable
from typing import Any

from fleet.serial_lines import MAX_WHEEL_SPEED, LineBuffer, parse_wheel_line, wheel_line
from localizer.events import OdometryMeasured
from sensors.sources import SensorSink

log = logging.getLogger(__name__)
__all__ = ["MAX_WHEEL_SPEED", "SerialWheelSource", "parse_wheel_line", "wheel_line"]


def _open_serial(port: str, baud: int) -> Any:
    import serial

    return serial.serial_for_url(port, baudrate=baud, timeout=0.2)


class SerialWheelSource:
    """Feed a robot's wheel speeds from a serial port on a thread.

    Args:
        robot: the robot's name.
        port: device path or pyserial URL (a stable name such as /dev/serial/by-id/... is
            best: it comes back under the same name after a reconnect).
        baud: baud rate.
        clock_ns: the clock stamping lines on receipt (the site clock on the server, the
            agent's monotonic clock on a robot).
        retry_s: pause between attempts to open a missing port, seconds.
        line_time: trust a line's own `t_ns` (it is on `clock_ns`'s clock); False: stamp
            every line on receipt (the on-robot agent: the robot controller's clock is not
            the agent's).

    Attributes:
        lines: good lines fed to the robot; bad_lines: lines skipped;
        connects: times the port was opened; connected: whether it is open now.
    """

    def __init__(
        self,
        robot: str,
        port: str,
        baud: int,
        clock_ns: Callable[[], int],
        *,
        retry_s: float = 1.0,
        line_time: bool = True,
    ) -> None:
        self.robot = robot
        self.line_time = line_time
        self.robots = (robot,)
        self._sink: SensorSink | None = None
        self.port = port
        self.baud = baud
        self.clock_ns = clock_ns
        self.retry_s = retry_s
        self.lines = 0
        self.bad_lines = 0
        self.connects = 0
        self.connected = False
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name=f"wheels-{robot}", daemon=True)

    def start(self, sink: SensorSink) -> None:
        """Read the port on a thread, feeding `sink` (a `FrameSource`)."""
        self._sink = sink
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        self._thread.join(timeout=5)

    def handle_line(self, raw: bytes) -> None:
        """Feed one received line (without its LF) to the robot, or count and skip it."""
        try:
            t_ns, v_left, v_right = parse_wheel_line(raw.decode("ascii"))
        except (UnicodeDecodeError, ValueError) as exc:
            self.bad_lines += 1
            log.warning(
                "robot %s: wheel line skipped on %s: %s",
                self.robot,
                self.port,
                exc,
                extra={"robot": self.robot, "port": self.port},
            )
            return
        stamp = t_ns if t_ns is not None and self.line_time else self.clock_ns()
        if self._sink is not None:
            self._sink(self.robot, OdometryMeasured(stamp, v_left, v_right))
        self.lines += 1

    def _run(self) -> None:
        warned = False
        while not self._stop.is_set():
            try:
                port = _open_serial(self.port, self.baud)
            except Exception as exc:  # pyserial raises SerialException / OSError / ValueError
                if not warned:
                    log.warning(
                        "robot %s: wheel port %s unavailable (%s); retrying every %.1f s",
                        self.robot,
                        self.port,
                        exc,
                        self.retry_s,
                        extra={"robot": self.robot, "port": self.port},
                    )
                    warned = True
                self._stop.wait(self.retry_s)
                continue
            warned = False
            self.connects += 1
            self.connected = True
            log.info("robot %s: wheel speeds from %s", self.robot, self.port)
            try:
                self._read(port)
            except Exception as exc:  # the device went away (EIO, unplugged)
                log.warning(
                    "robot %s: wheel port %s lost (%s); reconnecting",
                    self.robot,
                    self.port,
                    exc,
                    extra={"robot": self.robot, "port": self.port},
                )
            finally:
                self.connected = False
                try:
                    port.close()
                except Exception:
                    log.debug("closing %s failed", self.port, exc_info=True)
            self._stop.wait(self.retry_s)

    def _read(self, port: Any) -> None:
        lines = LineBuffer()  # an overlong piece without a line end is counted as bad
        while not self._stop.is_set():
            for raw in lines.feed(port.read(max(1, port.in_waiting))):
                self.handle_line(raw)

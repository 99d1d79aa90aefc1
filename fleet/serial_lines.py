"""The robot's serial lines (the wire format, pure): NMEA-style framing and the wheel-speed
line, shared by the server (`sensors/serial_wheels.py`, `serial_sink.py`) and the
on-robot agent (`agent/hardware.py`).

A line is `$<body>*<CS>\r\n`: ASCII, the body's fields separated by commas, `CS` the XOR of
every byte of the body (between `$` and `*`) as two uppercase hex digits. A wheel-speed
sample is `$IRODO,<t_ns>,<v_left>,<v_right>*<CS>` (m/s, |v| <= 20; `t_ns` may be empty:
stamped on receipt). Example: `$IRODO,,0.200,0.215*77`.
"""

from __future__ import annotations

import math

MAX_LINE_BYTES = 256
"""Longer input without a line end is not one of our lines."""


def nmea_checksum(body: str) -> str:
    """XOR of the bytes of `body` (the text between `$` and `*`), two hex digits."""
    cs = 0
    for b in body.encode("ascii"):
        cs ^= b
    return f"{cs:02X}"


def frame_line(body: str) -> str:
    """`$<body>*<CS>\\r\\n`."""
    return f"${body}*{nmea_checksum(body)}\r\n"


def unframe_line(line: str, what: str = "line") -> list[str]:
    """The comma-separated fields of a framed line, its checksum checked.

    Args:
        line: one line, with or without its CR LF.
        what: how errors name the line ("pose line", "wheel line").

    Raises:
        ValueError: not `$...*CS`, or a wrong checksum, naming the line.
    """
    text = line.strip()
    if not text.startswith("$") or "*" not in text:
        raise ValueError(f"{what} {line!r}: expected '$...*CS'")
    body, _, cs = text[1:].rpartition("*")
    expected = nmea_checksum(body)
    if expected != cs.upper():
        raise ValueError(f"{what} {line!r}: checksum {cs} != {expected}")
    return body.split(",")


MAX_WHEEL_SPEED = 20.0
"""m/s; faster is not a wheel speed (the same bound as `POST /robots/{name}/odometry`)."""


def wheel_line(v_left: float, v_right: float, t_ns: int | None = None) -> str:
    """The line for one wheel-speed sample (what the robot sends), with checksum and CR LF."""
    t = "" if t_ns is None else str(t_ns)
    return frame_line(f"IRODO,{t},{v_left:.4f},{v_right:.4f}")


def parse_wheel_line(line: str) -> tuple[int | None, float, float]:
    """(t_ns or None, v_left, v_right) of one line.

    Raises:
        ValueError: a malformed line, a wrong checksum or an absurd value, naming it.
    """
    parts = unframe_line(line, "wheel line")
    if len(parts) != 4 or parts[0] != "IRODO":
        raise ValueError(f"wheel line {line!r}: expected 4 fields starting with IRODO")
    _, t_text, vl_text, vr_text = parts
    try:
        t_ns = None if t_text == "" else int(t_text)
        v = (float(vl_text), float(vr_text))
    except ValueError:
        raise ValueError(f"wheel line {line!r}: t_ns must be an integer, speeds numbers") from None
    if t_ns is not None and t_ns < 0:
        raise ValueError(f"wheel line {line!r}: t_ns = {t_ns} is negative")
    for name, value in zip(("v_left", "v_right"), v, strict=True):
        if not math.isfinite(value) or abs(value) > MAX_WHEEL_SPEED:
            raise ValueError(
                f"wheel line {line!r}: {name} = {value} m/s is outside "
                f"[-{MAX_WHEEL_SPEED}, {MAX_WHEEL_SPEED}]"
            )
    return t_ns, v[0], v[1]


class LineBuffer:
    """Bytes as they come from a serial port -> complete lines (without the LF, blank ones
    dropped). Input longer than `MAX_LINE_BYTES` without a line end comes out as one
    overlong line, for the reader to count as bad."""

    def __init__(self) -> None:
        self._buf = b""

    def feed(self, chunk: bytes) -> list[bytes]:
        self._buf += chunk
        *lines, self._buf = self._buf.split(b"\n")
        out = [raw for raw in lines if raw.strip()]
        if len(self._buf) > MAX_LINE_BYTES:
            out.append(self._buf[:MAX_LINE_BYTES])
            self._buf = b""
        return out

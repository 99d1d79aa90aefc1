"""NMEA-style framing of the serial lines between the server and a robot.

A line is `$<body>*<CS>\r\n`: ASCII, the body's fields separated by commas, `CS` the XOR of
every byte of the body (between `$` and `*`) as two uppercase hex digits. The pose output
(`serial_sink`) and the wheel-speed input (`serial_wheels`) share this framing.
"""

from __future__ import annotations

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

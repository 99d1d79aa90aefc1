"""NMEA-style framing of the serial lines between the server and a robot: the format lives in
`fleet.serial_lines` (the on-robot agent reads the same lines)."""

from __future__ import annotations

from fleet.serial_lines import MAX_LINE_BYTES, frame_line, nmea_checksum, unframe_line

__all__ = ["MAX_LINE_BYTES", "frame_line", "nmea_checksum", "unframe_line"]

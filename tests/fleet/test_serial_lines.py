"""The robot's serial line format (fleet/serial_lines.py)."""

from __future__ import annotations

import pytest

from fleet.serial_lines import MAX_LINE_BYTES, LineBuffer, parse_wheel_line, wheel_line


def test_lines_split_across_chunks_blank_lines_dropped_overlong_cut() -> None:
    buf = LineBuffer()
    line = wheel_line(0.2, -0.215).encode()  # ends in CR LF
    assert buf.feed(line[:7]) == []
    assert buf.feed(line[7:] + b"\r\n" + line[:5]) == [line[:-1]]  # the blank line dropped
    assert buf.feed(b"") == []
    out = buf.feed(b"x" * MAX_LINE_BYTES)
    assert out == [line[:5] + b"x" * (MAX_LINE_BYTES - 5)]
    assert parse_wheel_line(line.decode()) == (None, 0.2, -0.215)
    with pytest.raises(ValueError, match=r"expected '\$...\*CS'"):
        parse_wheel_line(out[0].decode())

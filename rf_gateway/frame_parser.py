"""Incremental XBee API frame parser for a serial byte stream.

In API mode 1 a 0x7E can occur inside a frame (a frame id, an address byte), so the parser
follows the length field; it only resynchronises on the next 0x7E after a frame fails its
checksum (a 0x7E inside the failed span means the frame was cut short: counted as truncated).
In mode 2 a raw 0x7E is always a start delimiter, so one inside a frame marks it truncated.
"""

from __future__ import annotations

from dataclasses import dataclass, field

from rf_gateway.frames import ESCAPE, START, checksum


@dataclass
class ParserStats:
    """What a `StreamParser` has seen: good frames and each kind of rubbish it skipped."""

    frames: int = 0
    garbage_bytes: int = 0
    bad_checksums: int = 0
    truncated: int = 0
    bad_lengths: int = 0


@dataclass
class StreamParser:
    """Incremental API frame parser; `feed(bytes)` returns the complete frames' data.

    Never raises on bad input: garbage between frames, bad checksums, truncated frames and
    impossible lengths are counted in `stats` and skipped.

    Attributes:
        escaped: API mode 2 (escaping) instead of mode 1.
        max_length: longest frame data accepted, bytes; longer lengths count as bad.
    """

    escaped: bool = False
    max_length: int = 1024
    stats: ParserStats = field(default_factory=ParserStats)
    _buf: bytearray = field(default_factory=bytearray, repr=False)
    _in_frame: bool = field(default=False, repr=False)
    _escape_next: bool = field(default=False, repr=False)

    def feed(self, data: bytes) -> list[bytes]:
        """Consume `data`; return the frame data of every complete valid frame, in order."""
        out: list[bytes] = []
        for b in data:
            self._byte(b, out, count_garbage=True)
        return out

    def expire(self) -> None:
        """Drop a partial frame (call when the line went quiet mid-frame): counts truncated."""
        if self._in_frame:
            self.stats.truncated += 1
        self._reset()

    @property
    def pending(self) -> int:
        """Bytes of an incomplete frame held (0 between frames)."""
        return len(self._buf) if self._in_frame else 0

    def _reset(self) -> None:
        self._buf.clear()
        self._in_frame = False
        self._escape_next = False

    def _byte(self, b: int, out: list[bytes], *, count_garbage: bool) -> None:
        if not self._in_frame:
            if b == START:
                self._in_frame = True
            elif count_garbage:
                self.stats.garbage_bytes += 1
            return
        if self.escaped:
            if b == START:  # a delimiter never occurs escaped: the frame was cut short
                self.stats.truncated += 1
                self._reset()
                self._in_frame = True
                return
            if b == ESCAPE:
                self._escape_next = True
                return
            if self._escape_next:
                b ^= 0x20
                self._escape_next = False
        self._buf.append(b)
        if len(self._buf) < 2:
            return
        length = int.from_bytes(self._buf[:2], "big")
        if length == 0 or length > self.max_length:
            self.stats.bad_lengths += 1
            self._resync(out)
            return
        if len(self._buf) < length + 3:
            return
        data = bytes(self._buf[2 : 2 + length])
        if checksum(data) == self._buf[2 + length]:
            self.stats.frames += 1
            out.append(data)
            self._reset()
            return
        if not self.escaped and START in self._buf:
            self.stats.truncated += 1
        else:
            self.stats.bad_checksums += 1
        self._resync(out)

    def _resync(self, out: list[bytes]) -> None:
        """After a failed frame, look for the next delimiter inside what was consumed."""
        rest = bytes(self._buf) if not self.escaped else b""
        self._reset()
        for b in rest:
            self._byte(b, out, count_garbage=False)

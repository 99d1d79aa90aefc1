"""What came in over the XBee serial line, counted on the gateway side.

digi-xbee parses the frames itself: it skips bytes before a start delimiter, logs and drops a
frame with a bad checksum or a malformed body ("Error processing packet"), and delivers a
frame of an unknown type as `UnknownXBeePacket`. These counters hook its packet callback and
its reader's log so that the gateway can report (not only survive) a noisy line.
"""

from __future__ import annotations

import logging
from dataclasses import dataclass, field

from digi.xbee.packets.base import UnknownXBeePacket

DIGI_READER_LOGGER = "digi.xbee.reader"


@dataclass
class LinkStats:
    """Serial line counters (the reader-log counts are per process: digi-xbee's logger is).

    Attributes:
        frames_received: valid frames digi-xbee delivered.
        unknown_frames: of those, frames of a type digi-xbee does not know.
        invalid_frames: frames dropped for a bad checksum or a malformed body.
        read_errors: serial read errors (the port vanished under the reader).
    """

    frames_received: int = 0
    unknown_frames: int = 0
    invalid_frames: int = 0
    read_errors: int = 0
    _filter: ReaderLogCounter | None = field(default=None, repr=False, compare=False)

    def on_packet(self, packet: object) -> None:
        """digi-xbee packet callback."""
        self.frames_received += 1
        if isinstance(packet, UnknownXBeePacket):
            self.unknown_frames += 1

    def attach(self) -> None:
        """Start counting digi-xbee reader log records."""
        if self._filter is None:
            self._filter = ReaderLogCounter(self)
            logging.getLogger(DIGI_READER_LOGGER).addFilter(self._filter)

    def detach(self) -> None:
        if self._filter is not None:
            logging.getLogger(DIGI_READER_LOGGER).removeFilter(self._filter)
            self._filter = None


class ReaderLogCounter(logging.Filter):
    """Counts digi-xbee reader errors; drops the per-read "Serial exception" spam that a
    vanished port produces (counted as `read_errors`, reported once by the transport)."""

    def __init__(self, stats: LinkStats) -> None:
        super().__init__()
        self.stats = stats

    def filter(self, record: logging.LogRecord) -> bool:
        msg = str(record.msg)
        if msg.startswith("Error processing packet"):
            self.stats.invalid_frames += 1
        elif msg.startswith("Serial exception while reading"):
            self.stats.read_errors += 1
            return False
        return True

"""Several remote AT commands on the air at once over one digi-xbee device.

digi-xbee's synchronous `set_parameter` waits for each reply in turn (and concurrent calls on
one device gave spurious timeouts). The pipelined path instead writes remote AT request frames
(0x17) without waiting (`send_packet(sync=False)`, still from the one worker thread) and
matches the 0x97 replies to their requests here, by frame id, 64-bit address and command, as
digi-xbee's reader thread delivers them. A reply that comes after its request timed out finds
no waiter and is counted as late, never taken for another command.
"""

from __future__ import annotations

import asyncio
import threading
from dataclasses import dataclass

from digi.xbee.packets.common import RemoteATCommandResponsePacket


@dataclass(frozen=True)
class RemoteReply:
    """A remote AT reply: `status` 0 = OK (4 = transmission failure), `value` its data."""

    status: int
    value: bytes


@dataclass
class _Waiter:
    address: str
    command: str
    future: asyncio.Future[RemoteReply]
    loop: asyncio.AbstractEventLoop


class ReplyRouter:
    """Frame id -> the request waiting for its reply; thread-safe.

    Attributes:
        late_replies: replies whose request had already timed out (or was never ours).
        mismatched: replies whose frame id matched but address or command did not.
    """

    def __init__(self) -> None:
        self._lock = threading.Lock()
        self._pending: dict[int, _Waiter] = {}
        self.late_replies = 0
        self.mismatched = 0

    def in_use(self, frame_id: int) -> bool:
        with self._lock:
            return frame_id in self._pending

    def expect(
        self, frame_id: int, address: str, command: str, future: asyncio.Future[RemoteReply]
    ) -> None:
        """Register the request sent with `frame_id` (before the frame is written)."""
        with self._lock:
            self._pending[frame_id] = _Waiter(address, command, future, future.get_loop())

    def forget(self, frame_id: int) -> None:
        """The request timed out or failed to send: a reply to it is now late."""
        with self._lock:
            self._pending.pop(frame_id, None)

    def on_packet(self, packet: object) -> None:
        """digi-xbee packet callback (its reader thread)."""
        if not isinstance(packet, RemoteATCommandResponsePacket):
            return
        address = str(packet.x64bit_source_addr).upper()
        with self._lock:
            waiter = self._pending.get(packet.frame_id)
            if waiter is None:
                self.late_replies += 1
                return
            if waiter.address != address or waiter.command != packet.command.upper():
                self.mismatched += 1
                return
            del self._pending[packet.frame_id]
        reply = RemoteReply(packet.real_status, bytes(packet.command_value or b""))
        waiter.loop.call_soon_threadsafe(_settle, waiter.future, reply)


def _settle(future: asyncio.Future[RemoteReply], reply: RemoteReply) -> None:
    if not future.done():
        future.set_result(reply)

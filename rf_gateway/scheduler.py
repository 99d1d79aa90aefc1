"""Command slots granted by priority: the in-flight limit and the bounded queue.

At most `limit` commands are on the air at once; waiting commands are served by priority
(identification before LED housekeeping before battery polls), first come first served within
one priority. At most `max_waiting` may wait: more raise `QueueFullError`.
"""

from __future__ import annotations

import asyncio
import heapq
from collections.abc import AsyncIterator
from contextlib import asynccontextmanager
from enum import IntEnum

from rf_gateway.errors import RfGatewayError


class Priority(IntEnum):
    """Command priority; lower is served first."""

    IDENTIFY = 0
    HOUSEKEEPING = 1
    BATTERY = 2


class QueueFullError(RfGatewayError):
    """Too many radio commands are waiting; the caller should try again later."""


class PrioritySlots:
    """A semaphore whose waiters are woken by priority (then arrival order).

    Args:
        limit: commands in flight at once (about 4 for an XBee network).
        max_waiting: longest queue of waiting commands.
    """

    def __init__(self, limit: int, max_waiting: int) -> None:
        if limit < 1 or max_waiting < 0:
            raise ValueError(f"slots: limit {limit} must be >= 1, max_waiting {max_waiting} >= 0")
        self.limit = limit
        self.max_waiting = max_waiting
        self._free = limit
        self._heap: list[tuple[int, int, asyncio.Future[None]]] = []
        self._seq = 0
        self._waiting = 0  # futures in the heap not yet handed a slot nor cancelled
        self.peak_in_flight = 0

    @property
    def in_flight(self) -> int:
        return self.limit - self._free

    @property
    def waiting(self) -> int:
        """Commands waiting for a slot (kept as a count: O(1) with thousands queued)."""
        return self._waiting

    async def acquire(self, priority: int) -> None:
        """Wait for a slot. Raises QueueFullError when `max_waiting` are already waiting."""
        if self._free > 0 and self.waiting == 0:
            self._take()
            return
        if self.waiting >= self.max_waiting:
            raise QueueFullError(f"{self.waiting} radio commands already waiting")
        fut: asyncio.Future[None] = asyncio.get_running_loop().create_future()
        self._seq += 1
        heapq.heappush(self._heap, (int(priority), self._seq, fut))
        self._waiting += 1
        try:
            await fut
        except asyncio.CancelledError:
            if fut.done() and not fut.cancelled():
                self.release()  # the slot was handed over just as we were cancelled
            else:
                self._waiting -= 1
            raise

    def _take(self) -> None:
        self._free -= 1
        self.peak_in_flight = max(self.peak_in_flight, self.in_flight)

    def release(self) -> None:
        """Give a slot back, to the best waiter if any."""
        while self._heap:
            _, _, fut = heapq.heappop(self._heap)
            if not fut.done():
                fut.set_result(None)  # the slot passes straight to the waiter
                self._waiting -= 1
                return
        self._free += 1

    @asynccontextmanager
    async def slot(self, priority: int) -> AsyncIterator[None]:
        """`async with slots.slot(priority):` holds one in-flight slot."""
        await self.acquire(priority)
        try:
            yield
        finally:
            self.release()

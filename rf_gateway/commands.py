"""One radio command to one landmark, reliably: an in-flight slot granted by priority, sent
just before a sleeping landmark wakes, retried with exponential backoff; a landmark that
fails `max_tries` in a row is marked unreachable (an event) and, once it answers again,
reachable (`Gateway` sends everything through this)."""

from __future__ import annotations

import asyncio
from collections.abc import Awaitable, Callable
from typing import TypeVar

from rf_gateway.config import GatewayConfig, GatewayStats
from rf_gateway.errors import (
    LandmarkUnreachableError,
    RadioTimeout,
    RemoteCommandError,
    TransportUnavailable,
)
from rf_gateway.events import GatewayEvent, LandmarkReachable, LandmarkUnreachable
from rf_gateway.scheduler import Priority, PrioritySlots
from rf_gateway.wake import WakeTracker

T = TypeVar("T")


class RadioCommands:
    """Commands with retries and the landmarks' reachability.

    Args:
        config: the gateway's tuning (tries, backoff, timeout).
        stats: the gateway's counters (commands, retries, failures).
        slots: the in-flight slots, shared with the gateway's other radio use.
        wake: when each sleeping landmark wakes next.
        address_of: landmark id -> its radio address now.
        publish: where the reachability events go.
        clock_ns: stamps those events.
    """

    def __init__(
        self,
        config: GatewayConfig,
        stats: GatewayStats,
        slots: PrioritySlots,
        wake: WakeTracker,
        address_of: Callable[[int], str],
        publish: Callable[[GatewayEvent], None],
        clock_ns: Callable[[], int],
    ) -> None:
        self.config = config
        self.stats = stats
        self.slots = slots
        self.wake = wake
        self._address_of = address_of
        self._publish = publish
        self._clock_ns = clock_ns
        self.failures: dict[int, int] = {}
        self.unreachable: set[int] = set()

    def forget(self, lid: int) -> None:
        """A landmark left the map: forget its failures."""
        self.failures.pop(lid, None)
        self.unreachable.discard(lid)

    async def run(self, lid: int, priority: Priority, send: Callable[[], Awaitable[T]]) -> T:
        """Send until it answers or the tries run out.

        Raises:
            LandmarkUnreachableError: it did not answer (it is marked unreachable).
            TransportUnavailable: the radio link was down on every try.
        """
        address = self._address_of(lid)
        last: Exception | None = None
        radio_failures = 0
        tries = self.config.unreachable_tries if lid in self.unreachable else self.config.max_tries
        for attempt in range(tries):
            if attempt:
                self.stats.retries += 1
                await asyncio.sleep(self.config.retry_backoff_s * 2 ** (attempt - 1))
            loop = asyncio.get_running_loop()
            delay = self.wake.send_delay_s(lid, loop.time())
            if delay > 0:  # a sleeping landmark: take a slot just before it wakes
                await asyncio.sleep(delay)
            try:
                async with self.slots.slot(priority):
                    self.stats.commands += 1
                    sent = loop.time()
                    result = await asyncio.wait_for(send(), self.config.command_timeout_s)
                    self.wake.answered(lid, sent, loop.time())
            except (RadioTimeout, TimeoutError) as exc:
                self.wake.forget(lid)
                last, radio_failures = exc, radio_failures + 1
            except RemoteCommandError as exc:
                last, radio_failures = exc, radio_failures + 1
                if not exc.retryable:
                    break
            except TransportUnavailable as exc:
                last = exc
            else:
                self._mark_reachable(lid)
                return result
        self.stats.failures += 1
        if radio_failures == 0 and isinstance(last, TransportUnavailable):
            raise last
        self._mark_unreachable(lid, radio_failures)
        cause = str(last) if last is not None and str(last) else type(last).__name__
        raise LandmarkUnreachableError(lid, address, radio_failures, cause)

    def _mark_reachable(self, lid: int) -> None:
        self.failures[lid] = 0
        if lid in self.unreachable:
            self.unreachable.discard(lid)
            self._publish(LandmarkReachable(self._clock_ns(), lid, self._address_of(lid)))

    def _mark_unreachable(self, lid: int, tries: int) -> None:
        self.failures[lid] = self.failures.get(lid, 0) + tries
        if lid not in self.unreachable and tries > 0:
            self.unreachable.add(lid)
            event = LandmarkUnreachable(self._clock_ns(), lid, self._address_of(lid), tries)
            self._publish(event)

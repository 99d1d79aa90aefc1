"""Fan-out of published events to any number of subscribers (robots, the web app)."""

from __future__ import annotations

import asyncio
from collections.abc import AsyncIterator
from typing import Generic, TypeVar

E = TypeVar("E")


class Subscription(Generic[E]):
    """A subscriber's bounded queue; iterate it with `async for`.

    When the subscriber falls behind by `maxsize` events the oldest is dropped (counted in
    `dropped`): for LED state the latest event is the one that matters.
    """

    def __init__(self, hub: Hub[E], maxsize: int) -> None:
        self._hub = hub
        self._queue: asyncio.Queue[E] = asyncio.Queue(maxsize)
        self.dropped = 0

    def put(self, event: E) -> None:
        if self._queue.full():
            self._queue.get_nowait()
            self.dropped += 1
        self._queue.put_nowait(event)

    async def get(self) -> E:
        """The next event (waits)."""
        return await self._queue.get()

    def get_nowait(self) -> E | None:
        """The next event, or None when none is waiting."""
        try:
            return self._queue.get_nowait()
        except asyncio.QueueEmpty:
            return None

    def close(self) -> None:
        """Stop receiving events."""
        self._hub.unsubscribe(self)

    def __aiter__(self) -> AsyncIterator[E]:
        return self._iterate()

    async def _iterate(self) -> AsyncIterator[E]:
        while True:
            yield await self._queue.get()


class Hub(Generic[E]):
    """Publishes each event to every open subscription."""

    def __init__(self, maxsize: int = 256) -> None:
        self.maxsize = maxsize
        self._subs: list[Subscription[E]] = []

    def subscribe(self, initial: E | None = None) -> Subscription[E]:
        sub: Subscription[E] = Subscription(self, self.maxsize)
        if initial is not None:
            sub.put(initial)
        self._subs.append(sub)
        return sub

    def unsubscribe(self, sub: Subscription[E]) -> None:
        if sub in self._subs:
            self._subs.remove(sub)

    def publish(self, event: E) -> None:
        for sub in list(self._subs):
            sub.put(event)

    def __len__(self) -> int:
        return len(self._subs)

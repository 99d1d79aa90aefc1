"""A publish/subscribe bus with a bounded queue per subscriber: the one drop-oldest queue of
irloc (the server's poses and site events, the gateway's LED states and events).

Publishers call `publish` from any thread and never block: a subscriber whose queue is full
loses its oldest item (counted in `dropped`), so a slow client never stalls the others (for
LED states the latest is the one that matters). Consumers read from asyncio
(`await sub.get_batch()`, `await sub.next()`, `async for item in sub`), from a plain thread
(`sub.get(timeout_s)`), or without waiting (`sub.drain()`, `sub.get_nowait()`).
Imports nothing of irloc's.
"""

from __future__ import annotations

import asyncio
import contextlib
import threading
from collections import deque
from collections.abc import AsyncIterator, Callable
from typing import Generic, TypeVar

T = TypeVar("T")


class Subscription(Generic[T]):
    """One consumer's bounded queue.

    Attributes:
        maxsize: items buffered before the oldest is dropped.
        dropped: items dropped because the consumer fell behind.
        delivered: items handed to the consumer.
    """

    def __init__(self, bus: Bus[T], maxsize: int, accept: Callable[[T], bool] | None) -> None:
        if maxsize < 1:
            raise ValueError(f"subscription maxsize must be >= 1, got {maxsize}")
        self._bus = bus
        self.maxsize = maxsize
        self.accept = accept
        self.dropped = 0
        self.delivered = 0
        self.closed = False
        self._items: deque[T] = deque()
        self._cond = threading.Condition()
        self._waiter: asyncio.Future[None] | None = None

    def offer(self, item: T) -> asyncio.Future[None] | None:
        """Queue `item` (dropping the oldest when full); returns the asyncio waiter to wake
        (the bus wakes all of one publish with one loop call), or None."""
        with self._cond:
            if len(self._items) >= self.maxsize:
                self._items.popleft()
                self.dropped += 1
                self._bus.dropped += 1
            self._items.append(item)
            self._cond.notify()
            waiter, self._waiter = self._waiter, None
        return waiter

    def get_nowait(self) -> T | None:
        """The oldest item, or None when none is queued."""
        with self._cond:
            if not self._items:
                return None
            self.delivered += 1
            return self._items.popleft()

    async def next(self) -> T:
        """Wait for the oldest item (on an event loop); RuntimeError once closed and empty."""
        while True:
            with self._cond:
                if self._items:
                    self.delivered += 1
                    return self._items.popleft()
                if self.closed:
                    raise RuntimeError("subscription closed")
                fut: asyncio.Future[None] = asyncio.get_running_loop().create_future()
                self._waiter = fut
            await fut

    def __aiter__(self) -> AsyncIterator[T]:
        return self._iterate()

    async def _iterate(self) -> AsyncIterator[T]:
        """Every item, oldest first, until closed."""
        while True:
            items = await self.get_batch()
            if not items and self.closed:
                return
            for item in items:
                yield item

    def drain(self) -> list[T]:
        """Everything queued now (possibly nothing), oldest first."""
        with self._cond:
            items = list(self._items)
            self._items.clear()
            self.delivered += len(items)
            return items

    async def get_batch(self) -> list[T]:
        """Wait until something is queued, then return all of it, oldest first."""
        while True:
            with self._cond:
                if self._items or self.closed:
                    items = list(self._items)
                    self._items.clear()
                    self.delivered += len(items)
                    return items
                fut: asyncio.Future[None] = asyncio.get_running_loop().create_future()
                self._waiter = fut
            await fut

    def get(self, timeout_s: float | None = None) -> T | None:
        """The oldest item, waiting up to `timeout_s` from a plain thread; None on timeout."""
        with self._cond:
            if not self._items:
                self._cond.wait(timeout_s)
            if not self._items:
                return None
            self.delivered += 1
            return self._items.popleft()

    def close(self) -> None:
        """Stop receiving (idempotent); a waiting `get_batch` returns what is left."""
        self._bus.unsubscribe(self)
        with self._cond:
            self.closed = True
            self._cond.notify_all()
            waiter, self._waiter = self._waiter, None
        if waiter is not None:
            with contextlib.suppress(RuntimeError):
                waiter.get_loop().call_soon_threadsafe(_wake, waiter)

    def __enter__(self) -> Subscription[T]:
        return self

    def __exit__(self, *exc: object) -> None:
        self.close()


def _wake(fut: asyncio.Future[None]) -> None:
    if not fut.done():
        fut.set_result(None)


def _wake_many(futs: list[asyncio.Future[None]]) -> None:
    for fut in futs:
        _wake(fut)


def _wake_all(waiters: list[asyncio.Future[None]]) -> None:
    """Wake asyncio waiters with one thread-safe call per event loop."""
    by_loop: dict[asyncio.AbstractEventLoop, list[asyncio.Future[None]]] = {}
    for w in waiters:
        by_loop.setdefault(w.get_loop(), []).append(w)
    for loop, futs in by_loop.items():
        with contextlib.suppress(RuntimeError):  # loop closed
            loop.call_soon_threadsafe(_wake_many, futs)


class Bus(Generic[T]):
    """Fan-out of items to subscribers.

    Attributes:
        published: items published.
        dropped: items dropped over all subscribers.
    """

    def __init__(self, default_maxsize: int = 256) -> None:
        self.default_maxsize = default_maxsize
        self.published = 0
        self.dropped = 0
        self._subs: tuple[Subscription[T], ...] = ()
        self._lock = threading.Lock()

    def subscribe(
        self,
        maxsize: int | None = None,
        accept: Callable[[T], bool] | None = None,
        *,
        initial: T | None = None,
    ) -> Subscription[T]:
        """A new subscription receiving what is published from now on (`accept` filters),
        `initial` first when given (e.g. the current state)."""
        sub = Subscription(self, maxsize or self.default_maxsize, accept)
        if initial is not None:
            sub.offer(initial)
        with self._lock:
            self._subs = (*self._subs, sub)
        return sub

    def unsubscribe(self, sub: Subscription[T]) -> None:
        with self._lock:
            self._subs = tuple(s for s in self._subs if s is not sub)

    def publish(self, item: T) -> None:
        """Offer `item` to every subscriber that accepts it (never blocks)."""
        self.published += 1
        waiters: list[asyncio.Future[None]] = []
        for sub in self._subs:
            if sub.accept is None or sub.accept(item):
                waiter = sub.offer(item)
                if waiter is not None:
                    waiters.append(waiter)
        if waiters:
            _wake_all(waiters)

    def __len__(self) -> int:
        return len(self._subs)

"""The bounded pose/event bus: slow subscribers drop their oldest items, others get all."""

from __future__ import annotations

import asyncio
import threading

from server.bus import Bus


def test_slow_subscriber_drops_oldest_and_fast_one_gets_everything() -> None:
    bus: Bus[int] = Bus(default_maxsize=4)
    slow = bus.subscribe()
    fast = bus.subscribe(maxsize=100)
    for i in range(10):
        bus.publish(i)
    assert slow.drain() == [6, 7, 8, 9] and slow.dropped == 6
    assert fast.drain() == list(range(10)) and fast.dropped == 0
    assert bus.published == 10 and bus.dropped == 6


def test_filter_and_close() -> None:
    bus: Bus[int] = Bus()
    even = bus.subscribe(accept=lambda i: i % 2 == 0)
    for i in range(6):
        bus.publish(i)
    assert even.drain() == [0, 2, 4]
    even.close()
    bus.publish(8)
    assert even.drain() == [] and len(bus) == 0


def test_async_consumer_is_woken_from_another_thread() -> None:
    bus: Bus[int] = Bus()

    async def consume() -> list[int]:
        sub = bus.subscribe()
        threading.Timer(0.05, lambda: [bus.publish(i) for i in range(3)]).start()
        got: list[int] = []
        while len(got) < 3:
            got += await asyncio.wait_for(sub.get_batch(), 5)
        sub.close()
        return got

    assert asyncio.run(consume()) == [0, 1, 2]


def test_threaded_get_times_out_with_none() -> None:
    bus: Bus[int] = Bus()
    sub = bus.subscribe()
    assert sub.get(timeout_s=0.01) is None
    bus.publish(5)
    assert sub.get(timeout_s=0.01) == 5 and sub.delivered == 1

"""The bounded pose/event bus: slow subscribers drop their oldest items, others get all."""

from __future__ import annotations

import asyncio
import threading

from pubsub.bus import Bus


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


def test_every_subscriber_gets_every_event_in_order() -> None:
    async def main() -> tuple[list[int], list[int], int]:
        hub: Bus[int] = Bus(8)
        a, b = hub.subscribe(), hub.subscribe(initial=-1)
        for i in range(3):
            hub.publish(i)
        got_a = [await a.next() for _ in range(3)]
        got_b = []
        async for ev in b:
            got_b.append(ev)
            if ev == 2:
                break
        a.close()
        hub.publish(3)
        return got_a, got_b, len(hub)

    assert asyncio.run(main()) == ([0, 1, 2], [-1, 0, 1, 2], 1)


def test_a_slow_subscriber_loses_the_oldest_events() -> None:
    async def main() -> tuple[list[int | None], int]:
        hub: Bus[int] = Bus(3)
        sub = hub.subscribe()
        for i in range(5):
            hub.publish(i)
        return [sub.get_nowait() for _ in range(4)], sub.dropped

    assert asyncio.run(main()) == ([2, 3, 4, None], 2)

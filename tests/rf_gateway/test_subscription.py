from __future__ import annotations

import asyncio

from rf_gateway.subscription import Hub


def test_every_subscriber_gets_every_event_in_order() -> None:
    async def main() -> tuple[list[int], list[int], int]:
        hub: Hub[int] = Hub(maxsize=8)
        a, b = hub.subscribe(), hub.subscribe(initial=-1)
        for i in range(3):
            hub.publish(i)
        got_a = [await a.get() for _ in range(3)]
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
        hub: Hub[int] = Hub(maxsize=3)
        sub = hub.subscribe()
        for i in range(5):
            hub.publish(i)
        return [sub.get_nowait() for _ in range(4)], sub.dropped

    assert asyncio.run(main()) == ([2, 3, 4, None], 2)

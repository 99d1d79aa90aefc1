from __future__ import annotations

import asyncio

import pytest

from rf_gateway.scheduler import Priority, PrioritySlots, QueueFullError


def test_waiters_are_served_by_priority_then_arrival() -> None:
    async def main() -> list[str]:
        slots = PrioritySlots(limit=1, max_waiting=10)
        order: list[str] = []
        await slots.acquire(Priority.IDENTIFY)  # hold the only slot

        async def job(name: str, priority: Priority) -> None:
            async with slots.slot(priority):
                order.append(name)

        tasks = [
            asyncio.create_task(job(n, p))
            for n, p in [
                ("bat1", Priority.BATTERY),
                ("house", Priority.HOUSEKEEPING),
                ("ident1", Priority.IDENTIFY),
                ("bat2", Priority.BATTERY),
                ("ident2", Priority.IDENTIFY),
            ]
        ]
        await asyncio.sleep(0)
        slots.release()
        await asyncio.gather(*tasks)
        return order

    assert asyncio.run(main()) == ["ident1", "ident2", "house", "bat1", "bat2"]


def test_in_flight_never_exceeds_the_limit() -> None:
    async def main() -> int:
        slots = PrioritySlots(limit=4, max_waiting=100)

        async def job() -> None:
            async with slots.slot(Priority.HOUSEKEEPING):
                await asyncio.sleep(0.001)

        await asyncio.gather(*(job() for _ in range(40)))
        assert slots.in_flight == 0
        return slots.peak_in_flight

    assert asyncio.run(main()) == 4


def test_queue_full_and_cancelled_waiters() -> None:
    async def main() -> None:
        slots = PrioritySlots(limit=1, max_waiting=1)
        await slots.acquire(0)
        waiter = asyncio.create_task(slots.acquire(2))
        await asyncio.sleep(0)
        with pytest.raises(QueueFullError):
            await slots.acquire(1)
        waiter.cancel()
        with pytest.raises(asyncio.CancelledError):
            await waiter
        slots.release()  # no live waiter: the slot becomes free
        assert slots.in_flight == 0
        await slots.acquire(1)
        assert slots.in_flight == 1

    asyncio.run(main())


def test_bad_limits_raise() -> None:
    with pytest.raises(ValueError, match="limit 0"):
        PrioritySlots(0, 1)

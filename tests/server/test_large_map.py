"""Large maps stay cheap: an import is a handful of SQL statements (no per-row inserts or
commits), reads and `/healthz` come from the snapshot (no query), the scheduler counts its
waiters in O(1). Times are in bench/bench_large_site.py."""

from __future__ import annotations

import asyncio
from collections.abc import Iterator
from contextlib import contextmanager

from sqlalchemy import event

from bench.bench_large_site import grid_map
from rf_gateway.scheduler import PrioritySlots
from tests.server.conftest import Api


@contextmanager
def statements(api: Api, *, table: str | None = None) -> Iterator[list[str]]:
    """The kinds of the SQL statements run meanwhile (`table`: only those naming it; the
    site's own writers, such as the event writer, may query at any moment)."""
    seen: list[str] = []

    def count(conn: object, cursor: object, sql: str, *args: object) -> None:
        if table is None or table in sql:
            seen.append(sql.split()[0].upper())

    engine = api.services.engine
    event.listen(engine, "before_cursor_execute", count)
    try:
        yield seen
    finally:
        event.remove(engine, "before_cursor_execute", count)


def test_an_import_is_a_few_statements_and_reads_need_none(api: Api) -> None:
    doc = grid_map(3000)
    with statements(api) as seen:
        r = api.client.put("/api/v1/map", json=doc, headers=api.h("admin"))
        assert r.status_code == 200 and r.json() == {"landmarks": 3000}
    # landmarks (one executemany), audit, key use, the floor map's new version
    assert seen.count("INSERT") <= 4, seen
    assert len(seen) <= 16, seen  # (the floor's check and its map version: 4 more)
    with statements(api, table="landmarks") as seen:
        for _ in range(5):
            h = api.client.get("/healthz").json()
            assert h["landmarks"] == 3000
        assert len(api.services.map.list()) == 3000
        lmap = api.services.map.landmark_map()
    assert seen == []  # from the snapshot
    assert len(lmap) == 3000 and lmap.position(3000)[2] == 2.5
    assert api.services.map.landmark_map() is lmap  # built once per change
    got = api.client.get("/api/v1/landmarks/17", headers=api.h("viewer")).json()
    assert got["radio"] == "0013A20000000011" and got["z"] == 2.5


def test_the_scheduler_counts_thousands_of_waiters_in_constant_time() -> None:
    async def run() -> tuple[int, int, int]:
        slots = PrioritySlots(limit=1, max_waiting=50_000)
        await slots.acquire(1)
        waiters = [asyncio.ensure_future(slots.acquire(1)) for _ in range(20_000)]
        await asyncio.sleep(0)
        queued = slots.waiting
        waiters[5].cancel()
        await asyncio.sleep(0)
        after_cancel = slots.waiting
        slots.release()
        await asyncio.sleep(0)
        for w in waiters:
            w.cancel()
        await asyncio.gather(*waiters, return_exceptions=True)
        return queued, after_cancel, slots.waiting

    assert asyncio.run(asyncio.wait_for(run(), 10)) == (20_000, 19_999, 0)

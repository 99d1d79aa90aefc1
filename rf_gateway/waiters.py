"""Callers waiting for a landmark's LED command, keyed by the request's sequence number."""

from __future__ import annotations

import asyncio
from collections.abc import Callable

ALL = 1 << 62
"""A sequence number above every real one: settles every waiter of a landmark."""


class SeqWaiters:
    """Futures per landmark, each waiting for one sequence number (or a newer one) to settle.

    Latest wins: confirming sequence number `seq` answers every waiter of `seq` or older, so a
    superseded request is answered by the newer confirmation.
    """

    def __init__(self) -> None:
        self._waiters: dict[int, list[tuple[int, asyncio.Future[int]]]] = {}

    def add(self, landmark_id: int, seq: int) -> asyncio.Future[int]:
        """A future resolved with the confirmation time (ns) of `seq` or a newer command."""
        fut: asyncio.Future[int] = asyncio.get_running_loop().create_future()
        self._waiters.setdefault(landmark_id, []).append((seq, fut))
        return fut

    def resolve(self, landmark_id: int, seq: int, t_ns: int) -> None:
        self._settle(landmark_id, seq, lambda fut: fut.set_result(t_ns))

    def fail(self, landmark_id: int, seq: int, exc: BaseException) -> None:
        self._settle(landmark_id, seq, lambda fut: fut.set_exception(exc))

    def fail_all(self, exc: BaseException) -> None:
        for landmark_id in list(self._waiters):
            self.fail(landmark_id, ALL, exc)

    def _settle(
        self, landmark_id: int, seq: int, settle: Callable[[asyncio.Future[int]], None]
    ) -> None:
        keep = []
        for wanted, fut in self._waiters.get(landmark_id, []):
            if wanted > seq:
                keep.append((wanted, fut))
            elif not fut.done():
                settle(fut)
        self._waiters[landmark_id] = keep

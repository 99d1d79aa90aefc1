"""`PosePump`: takes every pose update from the pose bus in batches and hands each batch to a
function on a worker thread (doubt detection and the wizard, the map upkeep: consumers that
must not slow the server's loop)."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable, Sequence
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # the facades are handed in; typing only
    from live.facades import Robots
    from live.poses import PoseUpdate
    from pubsub.bus import Subscription

log = logging.getLogger(__name__)


class PosePump:
    """Feed `take` the pose bus's updates, a batch at most every `batch_s` seconds.

    Attributes:
        failures: batches whose `take` raised (logged; the pump goes on: the site may be
            restarting).
    """

    def __init__(
        self,
        robots: Robots,
        take: Callable[[Sequence[PoseUpdate]], object],
        *,
        batch_s: float,
        name: str,
    ) -> None:
        self.robots, self.take, self.batch_s, self.name = robots, take, batch_s, name
        self._sub: Subscription[PoseUpdate] | None = None
        self._task: asyncio.Task[None] | None = None
        self.failures = 0

    def start(self) -> None:
        """Subscribe (on the server's loop)."""
        self._sub = self.robots.subscribe_poses(maxsize=4096)
        self._task = asyncio.get_running_loop().create_task(self._pump(self._sub))

    async def stop(self) -> None:
        if self._sub is not None:
            self._sub.close()
        if self._task is not None:
            self._task.cancel()
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await self._task

    async def _pump(self, sub: Subscription[PoseUpdate]) -> None:
        while not sub.closed:
            batch = await sub.get_batch()
            if batch:
                try:
                    await asyncio.to_thread(self.take, batch)
                except Exception:
                    self.failures += 1
                    log.exception("%s: pose batch failed", self.name)
            await asyncio.sleep(self.batch_s)

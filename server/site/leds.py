"""The LED coordinator: robots' `LedRequest`s go to the gateway one at a time, and every
confirmed `LedsChanged` goes to every robot's localizer."""

from __future__ import annotations

import asyncio
import contextlib
import logging
from collections.abc import Callable, Iterable

from localizer.events import LedRequest
from rf_gateway.errors import RfGatewayError
from rf_gateway.gateway import Gateway
from server.site.robot import RobotRunner

log = logging.getLogger(__name__)


class LedCoordinator:
    """Serialise the robots' LED requests (identification sweeps) on the server's loop.

    Requests are applied in arrival order, one `set_leds` at a time; the gateway publishes
    each confirmed state to every subscriber, so all robots see every sweep step.

    Args:
        gateway: the site's gateway.
        runners: returns the robots to inform of LED changes.
        on_error: called with (robot name, error message) when a request fails.
    """

    def __init__(
        self,
        gateway: Gateway,
        runners: Callable[[], Iterable[RobotRunner]],
        on_error: Callable[[str, str], None] | None = None,
    ) -> None:
        self.gateway = gateway
        self.runners = runners
        self.on_error = on_error
        self.requests = 0
        self.failures = 0
        self._queue: asyncio.Queue[tuple[str, LedRequest]] = asyncio.Queue()
        self._loop = asyncio.get_running_loop()
        self._tasks: list[asyncio.Task[None]] = []

    def start(self) -> None:
        self._tasks = [
            self._loop.create_task(self._apply_loop()),
            self._loop.create_task(self._forward_loop()),
        ]

    async def stop(self) -> None:
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        self._tasks = []

    @property
    def waiting(self) -> int:
        """Requests not yet applied."""
        return self._queue.qsize()

    def request(self, robot: str, req: LedRequest) -> None:
        """Queue a robot's request (thread-safe, never blocks)."""
        self._loop.call_soon_threadsafe(self._queue.put_nowait, (robot, req))

    async def _apply_loop(self) -> None:
        while True:
            robot, req = await self._queue.get()
            self.requests += 1
            lit = self.gateway.landmarks.keys() if req.all_lit else req.lit
            try:
                await self.gateway.set_leds(lit)
            except (RfGatewayError, KeyError) as exc:
                self.failures += 1
                log.warning("LED request of robot %s failed: %s", robot, exc)
                if self.on_error is not None:
                    self.on_error(robot, str(exc))

    async def _forward_loop(self) -> None:
        sub = self.gateway.subscribe()
        try:
            async for event in sub:
                for runner in self.runners():
                    runner.post(event)
        finally:
            sub.close()

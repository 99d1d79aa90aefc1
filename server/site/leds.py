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

    One robot at a time owns the LEDs for its identification sweep: its requests are applied
    in order, one `set_leds` at a time, until it asks for all LEDs lit (the sweep's end) or
    stays silent for `owner_timeout_s`. Meanwhile other robots' requests wait (only each
    robot's latest is kept) and are served in arrival order afterwards. The gateway publishes
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
        *,
        owner_timeout_s: float = 2.0,
    ) -> None:
        self.gateway = gateway
        self.runners = runners
        self.on_error = on_error
        self.requests = 0
        self.failures = 0
        self._queue: asyncio.Queue[tuple[str, LedRequest]] = asyncio.Queue()
        self._loop = asyncio.get_running_loop()
        self._tasks: list[asyncio.Task[None]] = []
        self.owner_timeout_s = owner_timeout_s
        self.owner: str | None = None
        self._owner_seen = 0.0
        self._deferred: dict[str, LedRequest] = {}

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
        """Requests not yet applied (queued, and deferred while another robot sweeps)."""
        return self._queue.qsize() + len(self._deferred)

    def request(self, robot: str, req: LedRequest) -> None:
        """Queue a robot's request (thread-safe, never blocks)."""
        self._loop.call_soon_threadsafe(self._queue.put_nowait, (robot, req))

    async def _apply_loop(self) -> None:
        while True:
            timeout = None if self.owner is None else self.owner_timeout_s
            try:
                robot, req = await asyncio.wait_for(self._queue.get(), timeout)
            except TimeoutError:
                log.info("robot %s left the LEDs without ending its sweep", self.owner)
                self.owner = None
                await self._serve_deferred()
                continue
            if self.owner is not None and robot != self.owner:
                if req.all_lit:
                    self._deferred.pop(robot, None)  # all lit comes when the owner ends
                else:
                    self._deferred[robot] = req
                continue
            await self._apply(robot, req)
            await self._serve_deferred()

    async def _serve_deferred(self) -> None:
        while self.owner is None and self._deferred:
            robot = next(iter(self._deferred))
            await self._apply(robot, self._deferred.pop(robot))

    async def _apply(self, robot: str, req: LedRequest) -> None:
        """Apply one request; the robot owns the LEDs until it asks for all lit."""
        self.requests += 1
        self.owner = None if req.all_lit else robot
        self._owner_seen = self._loop.time()
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

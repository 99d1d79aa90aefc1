"""The LED coordinator: the robots' `LedRequest`s go to the gateway one at a time, and every
confirmed `LedsChanged` goes to every robot's localizer."""

from __future__ import annotations

import asyncio
import contextlib
import logging
import threading
from collections.abc import Callable, Iterable

from live.robots import RobotRunner
from localizer.events import LedRequest, LedsChanged
from rf_gateway.errors import LandmarkUnreachableError, RfGatewayError
from rf_gateway.gateway import Gateway

log = logging.getLogger(__name__)


class LedCoordinator:
    """Share the site's LEDs between the robots' identifications (on the server's loop).

    Robots identify by darkening one landmark of the lit ceiling at a time, so the robots
    that track go on with the others. Requests are applied one at a time in arrival order
    (only each robot's latest is kept), and each LED state a robot asked for is held at least
    `dwell_s` so that it gets the frames it needs. Every robot sees every state (the gateway
    publishes each to all subscribers), so the identifying robots learn from each other's
    probes. A state that is not "all lit" is never left behind: when no request came for
    `idle_restore_s`, every LED is lit again.

    While the LEDs are *held* (`hold(True)`, e.g. by the viewer's identification wizard,
    which switches them itself), requests wait and nothing is restored.

    The site's normal state ("all lit" of a request) is every landmark, or, with a schedule
    (`normal`, `live.leds`), the landmarks it lights: a probe that darkens one
    landmark darkens it among those, and `renormal()` applies a new schedule (keeping the
    last probe's landmark dark).

    Args:
        gateway: the site's gateway.
        runners: returns the robots to inform of LED changes.
        on_error: called with (robot name, error message) when a request fails, at most
            once per `error_quiet_s` for the same message (an identifying robot sends a
            request every few frames). A landmark that does not answer is not reported
            here: the gateway reports it once, as `landmark_unreachable`, and every
            request lighting it would fail the same way until it answers again.
        dwell_s: minimum time a requested state is held before the next is applied, s.
        idle_restore_s: light everything after this long without requests, seconds.
        error_quiet_s: the same failure is reported again only after this long, seconds.
    """

    def __init__(
        self,
        gateway: Gateway,
        runners: Callable[[], Iterable[RobotRunner]],
        on_error: Callable[[str, str], None] | None = None,
        *,
        dwell_s: float = 0.12,
        idle_restore_s: float = 1.5,
        error_quiet_s: float = 30.0,
    ) -> None:
        self.gateway = gateway
        self.runners = runners
        self.on_error = on_error
        self.dwell_s = dwell_s
        self.idle_restore_s = idle_restore_s
        self.requests = 0
        self.applied = 0
        self.failures = 0
        self.error_quiet_s = error_quiet_s
        self._reported: dict[str, float] = {}  # message -> loop time last reported
        self._pending: dict[str, LedRequest] = {}
        self._wake = asyncio.Event()
        self._loop = asyncio.get_running_loop()
        self._tasks: list[asyncio.Task[None]] = []
        self._held = False
        self._hold_lock = threading.Lock()
        self.normal: Callable[[], Iterable[int]] | None = None
        self._probe_dark: frozenset[int] = frozenset()

    def start(self) -> None:
        self.gateway.add_led_listener(self._forward)
        self._tasks = [self._loop.create_task(self._apply_loop())]
        if self.gateway.leds is not None:
            self._forward(self.gateway.leds)

    async def stop(self) -> None:
        self.gateway.remove_led_listener(self._forward)
        for task in self._tasks:
            task.cancel()
        for task in self._tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        self._tasks = []

    @property
    def waiting(self) -> int:
        """Requests not yet applied."""
        return len(self._pending)

    @property
    def held(self) -> bool:
        return self._held

    def request(self, robot: str, req: LedRequest) -> None:
        """Queue a robot's request (thread-safe, never blocks)."""
        self._loop.call_soon_threadsafe(self._put, robot, req)

    def hold(self, held: bool) -> None:
        """Hold the LEDs for someone who switches them directly (thread-safe): robots'
        requests wait until released."""
        with self._hold_lock:
            self._held = held
        self._loop.call_soon_threadsafe(self._wake.set)

    def _put(self, robot: str, req: LedRequest) -> None:
        self.requests += 1
        self._pending.pop(robot, None)  # latest wins, and goes to the back of the queue
        self._pending[robot] = req
        self._wake.set()

    def renormal(self) -> None:
        """The schedule changed: apply it (on the loop) unless a robot's request waits."""
        if "schedule" not in self._pending:
            self._put("schedule", LedRequest(all_lit=True))

    def _normal_set(self) -> set[int]:
        ids = set(self.gateway.landmarks)
        return ids if self.normal is None else ids & set(self.normal())

    def _lit_for(self, req: LedRequest) -> set[int]:
        if req.all_lit:
            return self._normal_set() - set(req.dark)
        return set(req.lit)

    async def _apply_loop(self) -> None:
        all_lit = True
        while True:
            timeout = None if all_lit else self.idle_restore_s
            self._wake.clear()
            if not self._pending or self._held:
                try:
                    await asyncio.wait_for(self._wake.wait(), timeout)
                except TimeoutError:
                    if not self._held and not self._pending:
                        log.info("no LED request for %.1f s: back to the normal state", timeout)
                        self._probe_dark = frozenset()
                        all_lit = await self._apply("site", LedRequest(all_lit=True))
                    continue
                continue
            robot = next(iter(self._pending))
            req = self._pending.pop(robot)
            if robot == "schedule":  # the latest probe's landmark stays dark
                req = LedRequest(all_lit=True, dark=self._probe_dark)
            else:
                self._probe_dark = frozenset(req.dark)
            lit = self._lit_for(req)
            all_lit = lit == self._normal_set()
            if self._current() == lit:
                continue
            all_lit = await self._apply(robot, req)
            if not all_lit:
                await asyncio.sleep(self.dwell_s)

    def _current(self) -> set[int] | None:
        state = self.gateway.leds
        if state is None or state.changing:
            return None
        return set(state.lit_among(self.gateway.landmarks))

    async def _apply(self, robot: str, req: LedRequest) -> bool:
        """Apply one request; True when every LED is now meant to be lit."""
        lit = self._lit_for(req)
        self.applied += 1
        try:
            await self.gateway.set_leds(lit)
        except (RfGatewayError, KeyError) as exc:
            self.failures += 1
            self._report(robot, exc)
        return lit == self._normal_set()

    def _report(self, robot: str, exc: Exception) -> None:
        if isinstance(exc, LandmarkUnreachableError):  # reported once by the gateway
            log.debug("LED request of robot %s: %s", robot, exc)
            return
        now, message = self._loop.time(), str(exc)
        last = self._reported.get(message)
        if last is not None and now - last < self.error_quiet_s:
            log.debug("LED request of robot %s failed again: %s", robot, message)
            return
        self._reported[message] = now
        log.warning("LED request of robot %s failed: %s", robot, message)
        if self.on_error is not None:
            self.on_error(robot, message)

    def _forward(self, event: LedsChanged) -> None:
        """Every LED state to every robot, synchronously as the gateway publishes it: an
        announced change reaches the localizers before the LEDs can switch."""
        for runner in self.runners():
            runner.post(event)

"""The gateway: one shared LED truth for the whole site, over any `Transport`.

`set_leds(lit_ids)` lights exactly those landmarks and darkens the others it controls; once
every landmark confirmed, a `localizer.events.LedsChanged` stamped with the time of the last
confirmation is published to every subscriber (each robot's localizer), so one robot's
identification sweep is seen by all. LED changes are serialised (`async with gw.sweep():`
holds the site for a whole identification sweep).

Reliability: every radio command goes through `commands.RadioCommands` (an in-flight slot
granted by priority: identification, then LED housekeeping, then battery polls; retries with
exponential backoff; a landmark that fails `max_tries` in a row is marked unreachable while
the others carry on). The start-up sweep is `startup_sweep`, the supply reads and discovery
`reads`. LED commands are latest-wins per landmark: each request gets a sequence
number, one syncer task per landmark sends the newest desired level and confirms only the
sequence number it sent, so a retry crossing a late reply neither loses nor double-counts a
change (the pin level itself is idempotent).
"""

from __future__ import annotations

import asyncio
import contextlib
import logging
import time
from collections.abc import AsyncIterator, Awaitable, Callable, Iterable, Mapping
from contextlib import asynccontextmanager
from contextvars import ContextVar
from functools import partial
from typing import TypeVar

from localizer.events import LedsChanged
from pubsub.bus import Bus, Subscription
from rf_gateway.battery import BatteryHistory, BatteryReading
from rf_gateway.commands import RadioCommands
from rf_gateway.config import GatewayConfig, GatewayStats
from rf_gateway.errors import (
    RfGatewayError,
    TransportUnavailable,
    UnknownLandmarkError,
)
from rf_gateway.events import (
    GatewayEvent,
    TransportStateChanged,
)
from rf_gateway.reads import LandmarkReads
from rf_gateway.scheduler import Priority, PrioritySlots
from rf_gateway.startup_sweep import StartupSweep
from rf_gateway.transport import (
    Transport,
    TransportState,
    normalize_landmark_radios,
)
from rf_gateway.waiters import ALL, SeqWaiters
from rf_gateway.wake import WakeTracker

log = logging.getLogger(__name__)
T = TypeVar("T")
_SWEEP_OWNER: ContextVar[int | None] = ContextVar("rf_gateway_sweep_owner", default=None)


class Gateway(StartupSweep, LandmarkReads):
    """Switch and read the site's landmarks through `transport`.

    Args:
        transport: the radio link (`SimTransport`, `XBeeTransport`).
        landmarks: landmark id -> 64-bit radio address (16 hex digits).
        config: tuning.
        clock_ns: the clock stamping events, nanoseconds (default `time.monotonic_ns`).
    """

    def __init__(
        self,
        transport: Transport,
        landmarks: Mapping[int, str],
        config: GatewayConfig | None = None,
        *,
        clock_ns: Callable[[], int] = time.monotonic_ns,
    ) -> None:
        self.transport = transport
        self.config = config or GatewayConfig()
        self.clock_ns = clock_ns
        self.stats = GatewayStats()
        self.batteries = BatteryHistory(self.config.battery)
        self._addresses = normalize_landmark_radios(landmarks)
        self._slots = PrioritySlots(self.config.max_in_flight, self.config.max_waiting)
        self.wake = WakeTracker(self.config.sleep)
        self._commands = RadioCommands(
            self.config,
            self.stats,
            self._slots,
            self.wake,
            lambda lid: self._addresses[lid],
            self._publish_event,
            clock_ns,
        )
        self._desired: dict[int, tuple[bool, int]] = {}  # id -> (level, seq)
        self._confirmed: dict[int, tuple[bool, int, int]] = {}  # id -> (level, seq, t_ns)
        self._waiters = SeqWaiters()
        self._led_priority: dict[int, Priority] = {}
        self._syncers: dict[int, asyncio.Task[None]] = {}
        self._seq = 0
        self._sweep_lock = asyncio.Lock()
        self._broadcasting: frozenset[int] = frozenset()  # LEDs a broadcast is switching
        self._believed: set[int] = set()  # lit by the start-up broadcast, not read back yet
        self._leds_hub: Bus[LedsChanged] = Bus(self.config.subscriber_queue)
        self._led_listeners: list[Callable[[LedsChanged], None]] = []
        self._battery_listeners: list[Callable[[BatteryReading], None]] = []
        self._events_hub: Bus[GatewayEvent] = Bus(self.config.subscriber_queue)
        self._last_leds: LedsChanged | None = None
        self._battery_task: asyncio.Task[None] | None = None
        self._start_task: asyncio.Task[None] | None = None

    # -- lifecycle -------------------------------------------------------------------------
    async def start(self) -> None:
        """Open the transport (a failure leaves it reopening in the background), start the
        battery schedule and light every LED in the background (`light_all_on_start`)."""
        listen = getattr(self.transport, "on_state_change", None)
        if listen is not None:
            listen(self._on_transport_state)
        try:
            await self.transport.open()
        except TransportUnavailable as exc:
            log.warning("radio not available yet: %s", exc)
        loop = asyncio.get_running_loop()
        if self.config.battery.interval_s is not None:
            self._battery_task = loop.create_task(self._battery_loop())
        if self.config.light_all_on_start:
            await self._sweep_lock.acquire()  # held until lit: LED requests queue behind
            self._start_task = loop.create_task(self._light_all())

    async def close(self) -> None:
        """Stop the schedule and the syncers, close the transport."""
        background = [self._battery_task, self._start_task, *self._syncers.values()]
        tasks = [t for t in background if t is not None]
        for task in tasks:
            task.cancel()
        for task in tasks:
            with contextlib.suppress(asyncio.CancelledError, Exception):
                await task
        self._waiters.fail_all(TransportUnavailable("the gateway was closed"))
        await self.transport.close()

    def _on_transport_state(self, state: TransportState) -> None:
        self._events_hub.publish(TransportStateChanged(self.clock_ns(), state))

    def _publish_event(self, event: GatewayEvent) -> None:
        self._events_hub.publish(event)

    async def _command(self, lid: int, priority: Priority, send: Callable[[], Awaitable[T]]) -> T:
        """One command to one landmark with retries (`commands.RadioCommands.run`)."""
        return await self._commands.run(lid, priority, send)

    # -- landmarks -----------------------------------------------------------------------
    @property
    def landmarks(self) -> dict[int, str]:
        """Landmark id -> radio address (a copy)."""
        return dict(self._addresses)

    @property
    def unreachable(self) -> frozenset[int]:
        return frozenset(self._commands.unreachable)

    def address_of(self, landmark_id: int) -> str:
        """Radio address of a landmark; UnknownLandmarkError names an unknown id."""
        try:
            return self._addresses[landmark_id]
        except KeyError:
            raise UnknownLandmarkError(landmark_id) from None

    def update_landmarks(self, landmarks: Mapping[int, str]) -> None:
        """Replace the id -> address map (after a map edit); forgets removed landmarks."""
        new = normalize_landmark_radios(landmarks)
        for lid in set(self._addresses) - set(new):
            task = self._syncers.pop(lid, None)
            if task is not None:
                task.cancel()
            self._waiters.fail(lid, ALL, UnknownLandmarkError(lid))
            self._desired.pop(lid, None)
            self._confirmed.pop(lid, None)
            self._commands.forget(lid)
            self.batteries.forget(lid)
        for lid, address in new.items():
            if self._addresses.get(lid) not in (None, address):
                self._confirmed.pop(lid, None)  # a new radio: its LED state is unknown
        self._addresses = new

    # -- subscriptions ---------------------------------------------------------------------
    def subscribe(self) -> Subscription[LedsChanged]:
        """LED state events for one consumer; the current state (if any) comes first."""
        return self._leds_hub.subscribe(initial=self._last_leds)

    def add_led_listener(self, listener: Callable[[LedsChanged], None]) -> None:
        """Call `listener` with every LED state synchronously, as it is published (before
        any radio command of an announced change is sent): for consumers that must know
        of a change before the LEDs can switch, such as the robots' localizers."""
        self._led_listeners.append(listener)

    def remove_led_listener(self, listener: Callable[[LedsChanged], None]) -> None:
        with contextlib.suppress(ValueError):
            self._led_listeners.remove(listener)

    def add_battery_listener(self, listener: Callable[[BatteryReading], None]) -> None:
        """Call `listener` with every supply reading (scheduled or asked for) synchronously,
        before `battery` returns it: e.g. to store it."""
        self._battery_listeners.append(listener)

    def remove_battery_listener(self, listener: Callable[[BatteryReading], None]) -> None:
        with contextlib.suppress(ValueError):
            self._battery_listeners.remove(listener)

    def subscribe_events(self) -> Subscription[GatewayEvent]:
        """Gateway events: unreachable/reachable landmarks, low battery, transport state."""
        return self._events_hub.subscribe()

    @property
    def leds(self) -> LedsChanged | None:
        """The last published LED state."""
        return self._last_leds

    # -- LED control -------------------------------------------------------------------------
    @asynccontextmanager
    async def sweep(self) -> AsyncIterator[Gateway]:
        """Hold the site's LEDs for one identification sweep (re-entrant in one task)."""
        if _SWEEP_OWNER.get() == id(self):
            yield self
            return
        async with self._sweep_lock:
            token = _SWEEP_OWNER.set(id(self))
            try:
                yield self
            finally:
                _SWEEP_OWNER.reset(token)

    async def set_leds(
        self, lit_ids: Iterable[int], *, priority: Priority = Priority.IDENTIFY
    ) -> LedsChanged:
        """Light exactly `lit_ids`, darken every other controlled landmark.

        Returns:
            The published state, stamped with the time the last landmark confirmed.

        Raises:
            UnknownLandmarkError: an id without a radio address (nothing is sent).
            LandmarkUnreachableError: a landmark did not confirm (the others were applied and
                the confirmed state was published).
            TransportUnavailable: the radio link is down.
        """
        lit = {int(i) for i in lit_ids}
        for lid in sorted(lit):
            self.address_of(lid)
        targets = {lid: lid in lit for lid in self._addresses}
        async with self.sweep():
            return await self._apply(targets, priority)

    async def led(self, landmark_id: int, on: bool) -> LedsChanged:
        """Switch one landmark's LED (housekeeping priority); raises as `set_leds`."""
        self.address_of(landmark_id)
        async with self.sweep():
            return await self._apply({landmark_id: on}, Priority.HOUSEKEEPING)

    async def blink(self, landmark_id: int) -> LedsChanged:
        """Toggle one LED `blink_count` times (to find it on the ceiling), then restore it."""
        self.address_of(landmark_id)
        async with self.sweep():
            level = self._desired.get(landmark_id, (True, 0))[0]
            half = self.config.blink_period_s / 2.0
            event = self._last_leds
            for _ in range(self.config.blink_count):
                for target in (not level, level):
                    event = await self._apply({landmark_id: target}, Priority.HOUSEKEEPING)
                    await asyncio.sleep(half)
            return event if event is not None else self._publish_state()

    async def _apply(self, targets: Mapping[int, bool], priority: Priority) -> LedsChanged:
        waits: list[tuple[int, asyncio.Future[int]]] = []
        loop = asyncio.get_running_loop()
        for lid, level in targets.items():
            confirmed = self._confirmed.get(lid)
            pending = lid in self._syncers
            if (
                self.config.skip_confirmed
                and not pending
                and confirmed is not None
                and confirmed[0] == level
            ):
                self.stats.skipped += 1
                continue
            if pending and self._desired[lid][0] == level:
                seq = self._desired[lid][1]  # already on its way: wait for that command
            else:
                self._seq += 1
                seq = self._seq
                self._desired[lid] = (level, seq)
            fut = self._waiters.add(lid, seq)
            self._led_priority[lid] = min(self._led_priority.get(lid, priority), priority)
            waits.append((lid, fut))
            if not pending:
                self._syncers[lid] = loop.create_task(self._sync_led(lid))
        if waits:
            self._publish_state(announce=True)  # these LEDs are unknown until confirmed
        results = await asyncio.gather(*(f for _, f in waits), return_exceptions=True)
        event = self._publish_state()
        errors = [r for r in results if isinstance(r, BaseException)]
        if errors:
            raise errors[0]
        return event

    def _publish_state(self, *, announce: bool = False) -> LedsChanged:
        """Publish the confirmed state, with the LEDs whose commands are in flight as
        `changing`; stamped now when announcing commands about to be sent, else with the
        last confirmation."""
        ids = set(self._addresses)
        lit = frozenset(lid for lid in ids if self._confirmed.get(lid, (False, 0, 0))[0])
        changing = (frozenset(self._syncers) | self._broadcasting) & ids
        times = [c[2] for lid, c in self._confirmed.items() if lid in ids]
        t_ns = self.clock_ns() if announce or not times else max(times)
        if self._last_leds is not None:
            t_ns = max(t_ns, self._last_leds.t_ns)
        all_lit = bool(ids) and lit == ids
        event = LedsChanged(t_ns, frozenset() if all_lit else lit, all_lit, changing)
        self._last_leds = event
        self.stats.published += 1
        for listener in list(self._led_listeners):
            try:
                listener(event)
            except Exception:
                log.exception("LED listener failed")
        self._leds_hub.publish(event)
        return event

    async def _sync_led(self, lid: int) -> None:
        """Send the newest desired level of one landmark until it is confirmed."""
        try:
            while lid in self._addresses:
                level, seq = self._desired[lid]
                confirmed = self._confirmed.get(lid)
                if confirmed is not None and confirmed[1] >= seq:
                    break
                priority = self._led_priority.pop(lid, Priority.HOUSEKEEPING)
                address = self._addresses[lid]
                try:
                    await self._command(
                        lid, priority, partial(self.transport.set_pin, address, level)
                    )
                except Exception as exc:
                    self._waiters.fail(lid, seq, exc)
                    if self._desired[lid][1] == seq:
                        break
                    continue
                t_ns = self.clock_ns()
                self._confirmed[lid] = (level, seq, t_ns)
                self._believed.discard(lid)
                self._waiters.resolve(lid, seq, t_ns)
        finally:
            self._syncers.pop(lid, None)

    # -- sleep ---------------------------------------------------------------------------------
    async def set_awake_time(
        self, landmark_ids: Iterable[int], seconds: float, *, priority: Priority = Priority.IDENTIFY
    ) -> frozenset[int]:
        """Set how long each landmark stays awake after a message (XBee `ST`): a long
        window keeps sleeping landmarks polling every `poll_interval_s` (commands reach them
        within it instead of up to a sleep period) while robots identify; the usual `ST`
        lets them sleep again. Returns the landmarks that confirmed (a failure marks a
        landmark unreachable as any command does; nothing is raised for it)."""
        ids = sorted(int(i) for i in landmark_ids)
        for lid in ids:
            self.address_of(lid)  # UnknownLandmarkError before anything is sent

        async def one(lid: int) -> int:
            address = self._addresses[lid]
            send = partial(self.transport.set_awake_time, address, seconds)
            await self._command(lid, priority, send)
            self.wake.set_wake_s(lid, seconds, asyncio.get_running_loop().time())
            return lid

        results = await asyncio.gather(*(one(lid) for lid in ids), return_exceptions=True)
        for r in results:
            if isinstance(r, BaseException) and not isinstance(r, RfGatewayError):
                raise r
        return frozenset(r for r in results if isinstance(r, int))

"""The gateway: one shared LED truth for the whole site, over any `Transport`.

`set_leds(lit_ids)` lights exactly those landmarks and darkens the others it controls; once
every landmark confirmed, a `localizer.events.LedsChanged` stamped with the time of the last
confirmation is published to every subscriber (each robot's localizer), so one robot's
identification sweep is seen by all. LED changes are serialised (`async with gw.sweep():`
holds the site for a whole identification sweep).

Reliability: every radio command takes an in-flight slot granted by priority (identification,
then LED housekeeping, then battery polls; `PrioritySlots`), is retried with exponential
backoff, and a landmark that fails `max_tries` in a row is marked unreachable (event) while the
others carry on. LED commands are latest-wins per landmark: each request gets a sequence
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
from rf_gateway.battery import BatteryHistory, BatteryReading, read_all
from rf_gateway.config import GatewayConfig, GatewayStats
from rf_gateway.errors import (
    LandmarkUnreachableError,
    RadioTimeout,
    RemoteCommandError,
    RfGatewayError,
    TransportUnavailable,
    UnknownLandmarkError,
)
from rf_gateway.events import (
    GatewayEvent,
    LandmarkReachable,
    LandmarkUnreachable,
    LowBattery,
    TransportStateChanged,
)
from rf_gateway.scheduler import Priority, PrioritySlots
from rf_gateway.transport import (
    BroadcastTransport,
    DiscoveredRadio,
    Transport,
    TransportState,
    normalize_landmark_radios,
)
from rf_gateway.waiters import ALL, SeqWaiters
from rf_gateway.wake import WakeTracker

log = logging.getLogger(__name__)
T = TypeVar("T")
_SWEEP_OWNER: ContextVar[int | None] = ContextVar("rf_gateway_sweep_owner", default=None)


class Gateway:
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
        self._desired: dict[int, tuple[bool, int]] = {}  # id -> (level, seq)
        self._confirmed: dict[int, tuple[bool, int, int]] = {}  # id -> (level, seq, t_ns)
        self._waiters = SeqWaiters()
        self._led_priority: dict[int, Priority] = {}
        self._syncers: dict[int, asyncio.Task[None]] = {}
        self._seq = 0
        self._failures: dict[int, int] = {}
        self._unreachable: set[int] = set()
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

    @property
    def start_awake_s(self) -> float | None:
        """The `ST` the start-up sweep broadcasts to every landmark first (None: none:
        awake radios, no `start_awake_s`, or a transport that cannot broadcast)."""
        cfg = self.config
        if cfg.sleep is None or cfg.start_awake_s is None or not cfg.light_all_on_start:
            return None
        return cfg.start_awake_s if isinstance(self.transport, BroadcastTransport) else None

    async def _light_all(self) -> None:
        broadcast = False
        try:
            broadcast = await self._broadcast_start()
            if not broadcast:
                await self._apply(dict.fromkeys(self._addresses, True), Priority.IDENTIFY)
        except Exception as exc:  # logged; the state confirmed so far is published
            log.warning("lighting every landmark at start: %s", exc)
        finally:
            self._sweep_lock.release()
        if broadcast:
            await self._verify_believed()

    async def _broadcast_start(self) -> bool:
        """Start-up with sleeping landmarks (`start_awake_s`): light every LED by one
        broadcast, wait until every landmark has polled once (`broadcast_wait_s`), publish
        them lit (*believed*: robots identify at once) and open the wake window by a second
        broadcast (`ST`; the landmarks are awake after the first). False: no broadcast
        (the start-up sweep is one command per landmark)."""
        seconds, sleep, transport = self.start_awake_s, self.config.sleep, self.transport
        if seconds is None or sleep is None or not isinstance(transport, BroadcastTransport):
            return False
        ids = frozenset(self._addresses)
        self._broadcasting = ids
        self._publish_state(announce=True)  # unknown until every landmark took it
        try:
            await transport.broadcast_pin(True)
            self.stats.commands += 1
            self.stats.broadcasts += 1
            await asyncio.sleep(sleep.broadcast_wait_s)
        except RfGatewayError as exc:
            log.warning("broadcasting LED on to every landmark: %s", exc)
            return False
        finally:
            self._broadcasting = frozenset()
        t_ns = self.clock_ns()
        for lid in ids - set(self._syncers):
            self._seq += 1
            self._desired[lid] = (True, self._seq)
            self._confirmed[lid] = (True, self._seq, t_ns)
            self._believed.add(lid)
        self._publish_state()
        try:
            await transport.broadcast_awake_time(seconds)
            self.stats.commands += 1
            self.stats.broadcasts += 1
        except RfGatewayError as exc:  # identification probes are then only slower
            log.warning("broadcasting ST to every landmark: %s", exc)
        return True

    async def _verify_believed(self) -> None:
        """Read back each LED believed lit since the start-up broadcast (housekeeping
        priority: after the robots' probes). One that missed the broadcast is switched as
        believed (announced, as any change); a confirmed command settles a landmark too. A
        missed one is dark while believed lit: a steady spot-less landmark, which neither
        identification (it compares switches) nor tracking (an occluded landmark) mistakes
        for anything."""
        transport = self.transport
        if not isinstance(transport, BroadcastTransport):
            return

        async def one(lid: int) -> None:
            seq = self._confirmed.get(lid, (False, 0, 0))[1]
            send = partial(transport.read_pin, self._addresses[lid])
            try:
                high = await self._command(lid, Priority.HOUSEKEEPING, send)
            except RfGatewayError:  # marked unreachable by `_command`: its LED is unknown
                if lid in self._believed and self._confirmed.get(lid, (0, -1))[1] == seq:
                    self._believed.discard(lid)
                    del self._confirmed[lid]
                    self._publish_state()
                return
            confirmed = self._confirmed.get(lid)
            if lid not in self._believed or confirmed is None or confirmed[1] != seq:
                return  # a command settled it meanwhile
            self._believed.discard(lid)
            if high != confirmed[0]:
                self.stats.broadcast_missed += 1
                del self._confirmed[lid]  # unknown: sent again
                async with self.sweep():
                    await self._apply({lid: confirmed[0]}, Priority.HOUSEKEEPING)

        await asyncio.gather(*(one(lid) for lid in sorted(self._believed)), return_exceptions=True)

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

    # -- landmarks -----------------------------------------------------------------------
    @property
    def landmarks(self) -> dict[int, str]:
        """Landmark id -> radio address (a copy)."""
        return dict(self._addresses)

    @property
    def unreachable(self) -> frozenset[int]:
        return frozenset(self._unreachable)

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
            self._failures.pop(lid, None)
            self._unreachable.discard(lid)
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

    # -- commands with retries ------------------------------------------------------------------
    async def _command(self, lid: int, priority: Priority, send: Callable[[], Awaitable[T]]) -> T:
        address = self._addresses[lid]
        last: Exception | None = None
        radio_failures = 0
        tries = self.config.unreachable_tries if lid in self._unreachable else self.config.max_tries
        for attempt in range(tries):
            if attempt:
                self.stats.retries += 1
                await asyncio.sleep(self.config.retry_backoff_s * 2 ** (attempt - 1))
            loop = asyncio.get_running_loop()
            delay = self.wake.send_delay_s(lid, loop.time())
            if delay > 0:  # a sleeping landmark: take a slot just before it wakes
                await asyncio.sleep(delay)
            try:
                async with self._slots.slot(priority):
                    self.stats.commands += 1
                    sent = loop.time()
                    result = await asyncio.wait_for(send(), self.config.command_timeout_s)
                    self.wake.answered(lid, sent, loop.time())
            except (RadioTimeout, TimeoutError) as exc:
                self.wake.forget(lid)
                last, radio_failures = exc, radio_failures + 1
            except RemoteCommandError as exc:
                last, radio_failures = exc, radio_failures + 1
                if not exc.retryable:
                    break
            except TransportUnavailable as exc:
                last = exc
            else:
                self._mark_reachable(lid)
                return result
        self.stats.failures += 1
        if radio_failures == 0 and isinstance(last, TransportUnavailable):
            raise last
        self._mark_unreachable(lid, radio_failures)
        cause = str(last) if last is not None and str(last) else type(last).__name__
        raise LandmarkUnreachableError(lid, address, radio_failures, cause)

    def _mark_reachable(self, lid: int) -> None:
        self._failures[lid] = 0
        if lid in self._unreachable:
            self._unreachable.discard(lid)
            event = LandmarkReachable(self.clock_ns(), lid, self._addresses[lid])
            self._events_hub.publish(event)

    def _mark_unreachable(self, lid: int, tries: int) -> None:
        self._failures[lid] = self._failures.get(lid, 0) + tries
        if lid not in self._unreachable and tries > 0:
            self._unreachable.add(lid)
            event = LandmarkUnreachable(self.clock_ns(), lid, self._addresses[lid], tries)
            self._events_hub.publish(event)

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

    # -- battery and discovery ----------------------------------------------------------------
    async def battery(self, landmark_id: int) -> BatteryReading:
        """Read one landmark's supply now (battery-poll priority), record it, tell the
        battery listeners, and raise a LowBattery event at or below the threshold; raises
        as `set_leds`."""
        address = self.address_of(landmark_id)
        mv = await self._command(
            landmark_id, Priority.BATTERY, lambda: self.transport.read_supply_mv(address)
        )
        reading = self.batteries.add(landmark_id, self.clock_ns(), int(mv))
        for listener in list(self._battery_listeners):
            listener(reading)
        if self.batteries.became_low(reading):
            event = LowBattery(reading.t_ns, landmark_id, reading.supply_mv, reading.days_left)
            self._events_hub.publish(event)
        return reading

    async def poll_batteries(self) -> list[BatteryReading]:
        """Read every landmark once (a landmark that fails is skipped, its event raised)."""
        return await read_all(self.battery, sorted(self._addresses), self.config.max_in_flight)

    async def _battery_loop(self) -> None:
        if self.config.light_all_on_start:
            async with self._sweep_lock:  # after the start-up sweep
                pass
        if self.config.battery.first_read_s > 0:
            await asyncio.sleep(self.config.battery.first_read_s)
        while self.config.battery.interval_s is not None:
            await self.poll_batteries()
            await asyncio.sleep(self.config.battery.interval_s)

    async def discover(self) -> list[DiscoveredRadio]:
        """Radios that answer node discovery (`discover_rounds` of them, merged) and are not
        in the landmark map, by address."""
        found: dict[str, DiscoveredRadio] = {}
        for _ in range(max(1, self.config.discover_rounds)):
            async with self._slots.slot(Priority.HOUSEKEEPING):
                for r in await self.transport.discover():
                    found.setdefault(r.address, r)
        known = set(self._addresses.values())
        return [r for a, r in sorted(found.items()) if a not in known]
